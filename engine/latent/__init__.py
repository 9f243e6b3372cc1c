"""Latent bank: codes, modes (GMM + silhouette), 2D projections and their geometry."""
