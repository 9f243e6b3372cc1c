"""How an ODMO model's decodes start, per frame: root, lowest foot, highest hand (README, rotation decoder).

    python bench/odmo_start.py --data DATA --model resources/models/bandai2-odmo --action run [--n 40]

Prints JSON: for the first ``--frames`` frames, the mean root height, the mean height of the lowest
foot joint and of the higher hand (found by name, ``engine.motion.contact``) over held-out windows of
``--action`` as they are, the same windows encoded and decoded with their own ends, and ``--n`` sampled
motions; and the mean foot speed per quarter second of each. A start-up transient shows as a rise the
real windows do not have.
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
from engine.generate import bank_window, decode_batch, encode_clips, sample
from engine.modelio import load_model
from engine.motion.contact import foot_joints, hand_joints
from engine.motion.datasets import load_folder


def profile(
    joints: np.ndarray, feet: list[int], hands: list[int], frames: int, fps: float
) -> dict[str, list[float]]:
    """Mean root height, lowest foot and highest hand per frame (first ``frames``) and foot speed per
    quarter second of ``joints`` (N, T, J, 3)."""
    speed = np.linalg.norm(np.diff(joints[:, :, feet], axis=1), axis=-1).mean(-1) * fps  # (N, T−1)
    quarter = max(1, round(fps / 4))
    return {
        "root_m": [round(float(v), 3) for v in joints[:, :frames, 0, 1].mean(0)],
        "lowest_foot_m": [round(float(v), 3) for v in joints[:, :frames][..., feet, 1].min(-1).mean(0)],
        "highest_hand_m": [round(float(v), 3) for v in joints[:, :frames][..., hands, 1].max(-1).mean(0)],
        "foot_speed_per_quarter_s": [
            round(float(speed[:, k : k + quarter].mean()), 2) for k in range(0, speed.shape[1], quarter)
        ],
    }


def main() -> int:
    """Print the three profiles."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--action", required=True)
    p.add_argument("--n", type=int, default=40)
    p.add_argument("--frames", type=int, default=20)
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    torch.set_num_threads(1)
    loaded = load_model(args.model)
    feet, hands = foot_joints(loaded.skeleton), hand_joints(loaded.skeleton)
    _, test_clips = heldout_split(load_folder(args.data).clips)
    long_enough = [
        c for c in test_clips if c.action == args.action and c.duration * loaded.fps >= loaded.window
    ]
    windows = [bank_window(loaded, c) for c in long_enough[: args.n]]
    codes, ends = encode_clips(loaded, windows)
    sets = {
        "real": np.stack([w.joints for w in windows]),
        "encoded": np.stack([m.joints for m in decode_batch(loaded, codes, args.action, ends)]),
        "sampled": np.stack([s.motion.joints for s in sample(loaded, args.action, args.n, args.seed)]),
    }
    report = {name: profile(js, feet, hands, args.frames, loaded.fps) for name, js in sets.items()}
    print(json.dumps({"model": args.model.name, "action": args.action, "n_real": len(windows), **report}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
