"""Does a model's planted-foot speed hold when the skate rule's tolerance moves (README, stop 46)?

    python bench/skate_tolerance.py --data DATA --model resources/models/bandai2-odmo
        [--actions walk walk-turn-left walk-turn-right run] [--n 100] [--tolerances 0.03 0.0301 0.05]

The skate rule (``engine.metrics.physics.foot_skate``) counts a foot joint as planted within 3 cm of the
clip's lowest foot height. A clean-up that parks swinging feet exactly at that height passes it on float
rounding; a millimetre further the same feet count. This samples ``--n`` motions per action as the card
does (``engine.generate.sample``, mode-preserving, seed 0; one model window each, float32 as the card
reads them) and reads the planted-foot speed at each tolerance, beside the held-out real windows' (the
centre model window of each clip, ``bench/heldout.py``), and the foot pop (99th-percentile
vertical foot speed). Prints JSON per action.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import heldout_split
from engine.generate import bank_window, sample
from engine.metrics.physics import foot_pop, foot_skate
from engine.modelio import load_model
from engine.motion.contact import foot_joints
from engine.motion.datasets import load_folder

TOLERANCES = (0.03, 0.0301, 0.035, 0.04, 0.05)


def figures(clips: list[np.ndarray], feet: list[int], fps: float, tolerances: list[float]) -> dict:
    """Planted-foot speed at each tolerance and foot pop of a set of (T, J, 3) clips, rounded."""
    skate = {f"{tol:g}": round(foot_skate(clips, feet, fps, tol), 3) for tol in tolerances}
    return {"skate_m_s": skate, "foot_pop_m_s": round(foot_pop(clips, feet, fps), 2)}


def main() -> int:
    """Print the figures per action."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--actions", nargs="+", default=["walk", "walk-turn-left", "walk-turn-right", "run"])
    p.add_argument("--n", type=int, default=100)
    p.add_argument("--tolerances", nargs="+", type=float, default=list(TOLERANCES))
    args = p.parse_args()
    torch.set_num_threads(1)
    loaded = load_model(args.model)
    feet, fps = foot_joints(loaded.skeleton), loaded.fps
    _, test_clips = heldout_split(load_folder(args.data).clips)
    report = {}
    for action in args.actions:
        clips = [c for c in test_clips if c.action == action and c.duration * fps >= loaded.window]
        real = [bank_window(loaded, c).joints.astype(np.float32) for c in clips]
        index = loaded.action_names.index(action)
        motions = sample(loaded, index, args.n, np.random.default_rng(0), strategy="mode_preserving")
        generated = [s.motion.joints.astype(np.float32) for s in motions]
        report[action] = {
            "real": figures(real, feet, fps, args.tolerances),
            "generated": figures(generated, feet, fps, args.tolerances),
        }
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
