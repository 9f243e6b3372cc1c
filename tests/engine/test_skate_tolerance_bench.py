"""bench/skate_tolerance.py: the planted-foot speed read at several tolerances of the skate rule."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bench import skate_tolerance
from bench.skate_tolerance import figures

REPO = Path(__file__).resolve().parents[2]


def test_a_foot_parked_just_above_the_tolerance_counts_a_millimetre_later() -> None:
    clip = np.zeros((41, 1, 3))
    clip[20:, 0, 1] = 0.0305  # from frame 20 the foot swings 3.05 cm up at 2 m/s
    clip[20:, 0, 0] = np.arange(21) * 0.1
    out = figures([clip], [0], 20.0, [0.03, 0.031])
    # at 3 cm only the 19 still steps are planted; at 3.1 cm the 20 swinging ones join them
    assert out["skate_m_s"] == {"0.03": 0.0, "0.031": round(2.0 * 20 / 40, 3)}
    lift = np.r_[np.zeros(39), 0.0305 * 20.0]  # the vertical speeds: one step of 0.61 m/s in 40
    assert out["foot_pop_m_s"] == round(float(np.quantile(lift, 0.99)), 2)


def test_the_bundled_model_and_real_walks_are_read_at_each_tolerance(
    bandai_dir: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    model = REPO / "resources" / "models" / "bandai2-odmo"
    argv = ["skate_tolerance", "--data", str(bandai_dir), "--model", str(model), "--actions", "walk"]
    monkeypatch.setattr(sys, "argv", [*argv, "--n", "20", "--tolerances", "0.03", "0.05"])
    assert skate_tolerance.main() == 0
    walk = json.loads(capsys.readouterr().out)["walk"]
    for side in ("real", "generated"):
        assert set(walk[side]["skate_m_s"]) == {"0.03", "0.05"}
        assert 0.05 < walk[side]["skate_m_s"]["0.03"] < walk[side]["skate_m_s"]["0.05"] < 2.0
    assert 0.5 < walk["real"]["foot_pop_m_s"] < 1.5  # real toes lift and land at about 1 m/s
