"""Shared fixtures: the real dataset folder, plus the fixture plugins each area owns."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch

pytest_plugins = ["tests.fixtures.procedural", "tests.fixtures.tiny_model"]

# Two cores shared with Xvfb and numba: more torch threads only oversubscribe them.
torch.set_num_threads(1)

_SHARED_BANDAI = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai-namco-2"


def bandai_root() -> Path | None:
    """The unpacked Bandai-Namco-2 folder from ODMO_BANDAI2 or ../shared, or None."""
    env = os.environ.get("ODMO_BANDAI2")
    for candidate in (Path(env) if env else None, _SHARED_BANDAI):
        if candidate is not None and (candidate / "data").is_dir():
            return candidate
    return None


@pytest.fixture(scope="session")
def bandai_dir() -> Path:
    """The real Bandai-Namco-2 dataset (skips only where it is absent; CI sets ODMO_BANDAI2)."""
    root = bandai_root()
    if root is None:
        pytest.skip("Bandai-Namco-2 not unpacked (set ODMO_BANDAI2)")
    return root
