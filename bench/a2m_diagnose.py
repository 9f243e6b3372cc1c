"""Why an Action2Motion folder scores what it does on the held-out Bandai clips (README, Action2Motion).

    python bench/a2m_diagnose.py --data DATA --model runs/bandai2-a2m [--n 100]

Prints JSON: per action, the bundled classifier's accuracy on prior samples, on the same samples read
only up to real clips' lengths (as real windows are read), and on reconstructions of the held-out
windows from their posterior means; the highest hand point above the first frame's root (generated,
real); and the mean joint speed in each third of the window (generated, real).
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
from engine.generators.a2m import generate_a2m, load_a2m
from engine.metrics.classifier import load_classifier
from engine.metrics.features import canonical_windows
from engine.motion.datasets import load_folder
from engine.motion.motion import Motion
from engine.train.windows import crop_windows, prepare_clips

CLASSIFIER = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo" / "classifier"
THIRDS = ((0, 20), (20, 40), (40, 59))


def thirds_speed(joints: np.ndarray, mask: np.ndarray, fps: float) -> list[float]:
    """Mean joint speed (m/s) over real frame pairs in each third of windows (N, T, J, 3)."""
    v = np.linalg.norm(np.diff(joints, axis=1), axis=-1).mean(-1) * fps
    m = mask[:, 1:] & mask[:, :-1]
    return [float((v[:, a:b] * m[:, a:b]).sum() / max(m[:, a:b].sum(), 1)) for a, b in THIRDS]


def hand_height(joints: np.ndarray, mask: np.ndarray, hands: list[int]) -> float:
    """Mean over windows of the highest hand point (m) above the first frame's root."""
    return float(np.where(mask[:, :, None], joints[:, :, hands, 1], -np.inf).max(axis=(1, 2)).mean())


def main() -> int:
    """Print the diagnostics as JSON."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--n", type=int, default=100, help="prior samples per action")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    torch.set_num_threads(1)
    loaded = load_a2m(args.model)
    classifier = load_classifier(CLASSIFIER)
    _, test = heldout_split(load_folder(args.data).clips)
    names = loaded.action_names
    hands = [j for j, n in enumerate(loaded.skeleton.names) if "hand" in n.lower()]
    prepared = prepare_clips(test, names, loaded.fps, loaded.window)
    real = crop_windows(prepared, np.arange(prepared.n_clips), np.random.default_rng(args.seed))
    with torch.inference_mode():
        x = torch.from_numpy(np.ascontiguousarray(real.joints, np.float32))
        rebuilt = loaded.model(
            x, torch.from_numpy(real.actions.astype(np.int64)), teacher=False, generator=None
        )
    rebuilt_pred = classifier.classify(rebuilt.joints.numpy(), real.mask)[1]
    generator = torch.Generator().manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    out: dict[str, dict] = {}
    generated = []
    for a, name in enumerate(names):
        joints, _ = generate_a2m(loaded, a, args.n, generator)
        windows = canonical_windows([Motion(j, loaded.fps, loaded.skeleton) for j in joints], loaded.window)
        generated.append(windows)
        full = np.ones(windows.shape[:2], bool)
        mine = real.actions == a
        lengths = real.mask[mine][rng.integers(0, int(mine.sum()), args.n)]
        out[name] = {
            "prior": float(np.mean(classifier.classify(windows)[1] == a)),
            "prior_at_real_lengths": float(np.mean(classifier.classify(windows, lengths)[1] == a)),
            "posterior_reconstruction": float(np.mean(rebuilt_pred[mine] == a)),
            "prior_predicted": np.bincount(classifier.classify(windows)[1], minlength=len(names)).tolist(),
            "hand_height_m": [
                hand_height(windows, full, hands),
                hand_height(real.joints[mine], real.mask[mine], hands),
            ],
        }
    gen = np.concatenate(generated)
    summary = {
        "prior": float(np.mean([v["prior"] for v in out.values()])),
        "prior_at_real_lengths": float(np.mean([v["prior_at_real_lengths"] for v in out.values()])),
        "posterior_reconstruction": float(np.mean(rebuilt_pred == real.actions)),
        "speed_thirds_m_s": [
            thirds_speed(gen, np.ones(gen.shape[:2], bool), loaded.fps),
            thirds_speed(real.joints, real.mask, loaded.fps),
        ],
    }
    print(json.dumps({"per_action": out, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
