"""Training throughput (windows/s) on CPU at the default sizes (T = 60, 21 joints, 10 actions, batch 128).

Synthetic smooth random clips; the full ``engine.train.train`` step is timed (cropping, canonical
facing, encoder, trajectory and motion generators with parallel scheduled sampling, losses, backward,
clipping, Adam). Run: ``python bench/train_speed.py [--threads 1 2] [--precision float32 bfloat16]
[--epochs 3] [--profile]``. Target: >= 300 windows/s on the 2-core CPU. ``--profile`` instead records where
a float32 step's time goes (torch.profiler, self CPU time per operator), to set against bench/ceiling.py's
matrix-product ceiling.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record
from engine.model.config import TRAIN_PRECISIONS, OdmoConfig
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton
from engine.train.epochs import TrainProgress
from engine.train.loop import train

N_ACTIONS, N_JOINTS = 10, 21


def synthetic_clips(n_per_action: int, rng: np.random.Generator) -> tuple[list[Motion], list[str]]:
    """Smooth random clips (40–200 frames at 20 fps) on a 21-joint chain skeleton with L/R names."""
    names = ["Hips"] + [f"J{i}_{'L' if i % 2 else 'R'}" for i in range(1, N_JOINTS)]
    parents = np.array([-1] + [max(0, i - 2) for i in range(1, N_JOINTS)])
    skeleton = Skeleton(tuple(names), parents, rng.normal(scale=0.1, size=(N_JOINTS, 3)))
    actions = [f"action{a}" for a in range(N_ACTIONS)]
    clips = []
    for a in actions:
        for _ in range(n_per_action):
            t = int(rng.integers(40, 201))
            joints = np.cumsum(rng.normal(scale=0.01, size=(t, N_JOINTS, 3)), axis=0)
            clips.append(Motion(joints.astype(np.float32), 20.0, skeleton, action=a))
    return clips, actions


def measure(
    threads: int, precision: str, epochs: int, clips: list[Motion], actions: list[str]
) -> dict[str, object]:
    """Steady-state windows/s of the last epoch with ``threads`` torch threads and ``precision``."""
    torch.set_num_threads(threads)
    config = OdmoConfig(
        n_actions=N_ACTIONS, n_joints=N_JOINTS, epochs=epochs, epoch_size=1024, train_precision=precision
    )
    last: list[TrainProgress] = []
    with tempfile.TemporaryDirectory() as out:
        train(clips, actions, Path(out), config, device="cpu", val_fraction=0.1, progress=last.append,
              bank_projections=("pca",), bank_k_range=(3, 3))  # fmt: skip
    final = [p for p in last if p.stage == "train" and p.epoch == epochs][-1]
    return {
        "threads": threads,
        "train_precision": precision,
        "batch (windows)": config.batch_size,
        "steps/s": round(final.steps_per_s, 2),
        "windows/s": round(final.windows_per_s, 1),
        "ms/step": round(1000 / final.steps_per_s, 1),
    }


MATMUL_OPS = ("aten::mm", "aten::addmm", "aten::bmm", "aten::baddbmm", "aten::matmul", "aten::linear")
LSTM_OPS = ("aten::mkldnn_rnn_layer", "aten::mkldnn_rnn_layer_backward")  # oneDNN's fused LSTM layers


def profile(threads: int, clips: list[Motion], actions: list[str], top: int = 12) -> list[dict[str, object]]:
    """Self CPU time of the ``top`` operators over one float32 epoch of 8 steps, and the shares of the LSTM
    layers and of the other matrix products."""
    from torch.profiler import ProfilerActivity
    from torch.profiler import profile as torch_profile

    torch.set_num_threads(threads)
    config = OdmoConfig(n_actions=N_ACTIONS, n_joints=N_JOINTS, epochs=1, epoch_size=1024)
    with tempfile.TemporaryDirectory() as out, torch_profile(activities=[ProfilerActivity.CPU]) as prof:
        train(clips, actions, Path(out), config, device="cpu", val_fraction=0.1,
              bank_projections=("pca",), bank_k_range=(3, 3))  # fmt: skip
    events = sorted(prof.key_averages(), key=lambda e: e.self_cpu_time_total, reverse=True)
    total = sum(e.self_cpu_time_total for e in events)

    def row(name: str, calls: object, micros: float) -> dict[str, object]:
        return {
            "operator": name,
            "calls": calls,
            "self CPU ms": round(micros / 1e3, 1),
            "share": f"{micros / total:.1%}",
        }

    rows = [row(e.key, e.count, e.self_cpu_time_total) for e in events[:top]]
    for name, ops in (("LSTM layers, forward and backward", LSTM_OPS), ("other matrix products", MATMUL_OPS)):
        rows.append(row(name, "", sum(e.self_cpu_time_total for e in events if e.key in ops)))
    rows.append(row("all operators", "", total))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--precision", nargs="+", default=["float32", "bfloat16"], choices=TRAIN_PRECISIONS)
    parser.add_argument("--epochs", type=int, default=3)
    parser.add_argument("--profile", action="store_true", help="profile a float32 epoch instead")
    parser.add_argument("--no-record", action="store_true", help="print only")
    args = parser.parse_args()
    clips, actions = synthetic_clips(20, np.random.default_rng(0))
    command = ("python bench/train_speed.py " + " ".join(sys.argv[1:])).strip()
    if args.profile:
        profiled = profile(max(args.threads), clips, actions)
        for row in profiled:
            print(row)
        if not args.no_record:
            record("Training step profile (CPU, float32)", profiled, command)
        return
    rows = [measure(n, p, args.epochs, clips, actions) for n in args.threads for p in args.precision]
    for row in rows:
        print(row)
    if not args.no_record:
        record("Training throughput (CPU)", rows, command)


if __name__ == "__main__":
    main()
