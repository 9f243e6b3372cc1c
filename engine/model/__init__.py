"""The ODMO networks: encoder, trajectory generator, motion generator, losses, baselines."""
