"""What opening a model loads: the estimators that only fitting needs stay unloaded (they cost the app's
start-up about a second; bench/interaction.py measures the start)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BUNDLED = Path(__file__).resolve().parents[2] / "resources" / "models" / "bandai2-odmo"
FIT_ONLY = ("sklearn.mixture", "sklearn.manifold", "sklearn.decomposition", "sklearn.metrics")

PROBE = f"""
import json, sys
from engine.generators import open_generator
generator = open_generator({str(BUNDLED)!r})
import engine.generate
generator.decode(generator.bank.codes[:1], generator.bank.actions[:1])
print(json.dumps(sorted(sys.modules)))
"""


def test_opening_and_decoding_the_bundled_model_loads_no_fitting_estimator():
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    loaded = set(json.loads(done.stdout.splitlines()[-1]))
    assert "torch" in loaded and "engine.latent.modes" in loaded
    assert not [m for m in FIT_ONLY if m in loaded]
