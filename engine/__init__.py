"""ODMO Explorer engine: motion I/O, the ODMO generator, latent bank, metrics and CLI (no Qt)."""

__version__ = "0.1.0"
