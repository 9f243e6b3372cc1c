"""Evaluation: classifier, FID, diversity, multimodality, APD, mode and trajectory metrics."""
