"""Reusable Qt views: take arrays, emit signals; know nothing of models."""
