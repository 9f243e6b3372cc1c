"""The ODMO Explorer application: state, controller, workers, main window."""
