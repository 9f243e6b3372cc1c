"""Training data preparation and the training loop."""
