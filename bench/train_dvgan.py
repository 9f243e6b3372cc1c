"""Train, evaluate and package the bundled DVGAN model on Bandai-Namco-2.

    python bench/train_dvgan.py --data "$(../shared/data/unpack)" --epochs 100 [--resume]

Trains ``engine.train.dvgan_loop.train_dvgan`` (RNN generator, dense critic) on the training part of the
held-out split every model of docs/RESULTS.md uses (bench/heldout.py), resuming from --work; with
``--hold-out-action A`` the clips of action A are left out of training as well (the phrase ablation:
its words must appear in other actions' phrases). Resumable.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch
from tqdm import tqdm

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.heldout import heldout_split
from engine.model.dvgan import DvganConfig
from engine.motion.datasets import load_folder
from engine.train.dvgan_loop import train_dvgan
from engine.train.epochs import TrainProgress


def parse_args() -> argparse.Namespace:
    """Command-line options."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--work", type=Path, default=Path("runs/bandai2-dvgan"), help="the trained model folder")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--generator", default="rnn", choices=("rnn", "cnn"))
    p.add_argument("--hold-out-action", help="leave this action's clips out of training (phrase ablation)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--resume", action="store_true")
    return p.parse_args()


def main() -> int:
    """Train the model folder in --work."""
    args = parse_args()
    torch.set_num_threads(args.threads)
    dataset = load_folder(args.data)
    train_clips, _ = heldout_split(dataset.clips)
    names = list(dataset.action_names)
    if args.hold_out_action:
        if args.hold_out_action not in names:
            raise SystemExit(f"--hold-out-action {args.hold_out_action!r}: not one of {', '.join(names)}")
        names.remove(args.hold_out_action)
        train_clips = [c for c in train_clips if c.action != args.hold_out_action]
    config = DvganConfig(
        n_actions=len(names), n_joints=dataset.skeleton.n_joints, epochs=args.epochs, generator=args.generator
    )
    bar = tqdm(total=config.epochs, desc="dvgan", unit="epoch")

    def show(p: TrainProgress) -> None:
        if p.step == p.steps:
            bar.n = p.epoch
            bar.set_postfix({k: f"{v:.3g}" for k, v in p.losses.items()} | {"w/s": f"{p.windows_per_s:.0f}"})
            bar.refresh()

    train_dvgan(
        train_clips, names, args.work, config, seed=args.seed, device="cpu", resume=args.resume, progress=show
    )
    bar.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
