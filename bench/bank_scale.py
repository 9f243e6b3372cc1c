"""Latent banks at scale: `odmo bank`'s streamed build of 10k to 1M windows, its wall time and peak memory.

``python bench/bank_scale.py --sizes 10000 100000 1000000`` builds each bank in a fresh process (so each
peak RSS is its own) with the bundled ODMO model, from synthetic clips made one at a time as a folder
reader would hand them over: 300 frames at the model's rate on its skeleton, windows every 30 frames
(9 per clip), ten actions and three styles. Steps as `odmo bank` takes them: encode (streamed, batches of
256 windows), the columnar metadata, modes and the PCA map (t-SNE and UMAP left out: their fit is the
next bullet of issue 17), save (atomic, format 3) and load. ``--all-at-once N`` adds a row encoding N
windows in one batch, the way banks were built before streaming.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.generate import BANK_BATCH
from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton

MODEL = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo"
FRAMES, STRIDE = 300, 30
STYLES = ("calm", "brisk", "tired")


def peak_mb() -> float:
    """Peak resident memory of this process so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class SyntheticClips(Sequence[Motion]):
    """``n`` clips made on demand (each from its own seed): the rest pose of ``skeleton`` swaying and
    walking along a random heading, so no more than one clip is in memory at a time."""

    def __init__(self, n: int, skeleton: Skeleton, fps: float, actions: Sequence[str]) -> None:
        self.n, self.skeleton, self.fps, self.actions = n, skeleton, fps, list(actions)
        rest = np.zeros((skeleton.n_joints, 3))
        for j, parent in enumerate(skeleton.parents):
            rest[j] = skeleton.offsets[j] + (rest[parent] if parent >= 0 else 0.0)
        self.rest = rest

    def __len__(self) -> int:
        """Number of clips."""
        return self.n

    def __getitem__(self, k: int) -> Motion:  # type: ignore[override]
        """Clip ``k``."""
        if not 0 <= k < self.n:
            raise IndexError(k)
        rng = np.random.default_rng(k)
        t = np.arange(FRAMES) / self.fps
        heading = rng.uniform(0, 2 * np.pi)
        root = np.c_[np.sin(heading) * t, np.zeros_like(t), np.cos(heading) * t] * rng.uniform(0.2, 1.5)
        sway = 0.05 * np.sin(
            2 * np.pi * rng.uniform(0.5, 2.0) * t[:, None, None] + rng.uniform(0, 6, (1, len(self.rest), 3))
        )
        joints = (self.rest[None] + root[:, None] + sway).astype(np.float32)
        meta = {"source": f"synthetic/clip_{k:07d}.bvh", "style": STYLES[k % len(STYLES)]}
        return Motion(joints, self.fps, self.skeleton, action=self.actions[k % len(self.actions)], meta=meta)


def build_one(windows: int, batch: int | None) -> dict[str, object]:
    """Build a bank of about ``windows`` windows the way `odmo bank` does; times (s), peak RSS (MB), size."""
    import torch

    from engine.generate import encode_bank_windows
    from engine.latent.bank import LatentBank, build_bank
    from engine.latent.columns import MetaColumns
    from engine.modelio import load_model

    torch.set_num_threads(1)
    loaded = load_model(MODEL, with_bank=False)
    per_clip = (FRAMES - loaded.window) // STRIDE + 1
    clips = SyntheticClips(-(-windows // per_clip), loaded.skeleton, loaded.fps, loaded.action_names)
    row: dict[str, object] = {
        "windows": 0,
        "clips": len(clips),
        "batch": batch or "all",
        "base MB": peak_mb(),
    }
    start = time.perf_counter()
    codes, ends, owners, starts = encode_bank_windows(loaded, clips, STRIDE, batch=batch or windows * 2)
    row |= {"windows": len(codes), "encode s": time.perf_counter() - start, "after encode MB": peak_mb()}
    if batch is None:
        return row
    start = time.perf_counter()
    names = loaded.action_names
    table = [{"source": f"synthetic/clip_{k:07d}.bvh", "style": STYLES[k % 3]} for k in range(len(clips))]
    meta = MetaColumns.from_table(
        table, owners, {"window_stride": np.full(len(owners), STRIDE), "window_start": starts}
    )
    bank = build_bank(
        codes,
        (np.arange(len(clips)) % len(names))[owners],
        ends,
        np.asarray([t["source"] for t in table], dtype=object)[owners],
        meta,
        names,
        projections=("pca",),
    )
    row |= {"modes + PCA s": time.perf_counter() - start}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "latent_bank.npz"
        start = time.perf_counter()
        bank.save(path)
        row |= {"save s": time.perf_counter() - start, "file MB": path.stat().st_size / 2**20}
        del bank, codes, ends, owners, starts, meta
        start = time.perf_counter()
        back = LatentBank.load(path)
        row |= {"load s": time.perf_counter() - start}
        assert len(back.codes) == row["windows"] and back.meta[0]["window_stride"] == STRIDE
    return row | {"peak MB": peak_mb()}


def main(argv: list[str] | None = None) -> int:
    """Build each size in its own process and publish the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--batch", type=int, default=BANK_BATCH)
    parser.add_argument("--all-at-once", type=int, nargs="*", default=[], metavar="N")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--no-save", action="store_true", help="print the table only")
    args = parser.parse_args(argv)
    if args.one is not None:
        print(json.dumps(build_one(args.one, args.batch or None)))
        return 0
    from bench._report import publish

    command = "python bench/bank_scale.py " + " ".join(sys.argv[1:] if argv is None else argv)
    rows = []
    for n, batch in [(n, 0) for n in args.all_at_once] + [(n, args.batch) for n in args.sizes]:
        out = subprocess.run(
            [sys.executable, __file__, "--one", str(n), "--batch", str(batch)],
            check=True,
            capture_output=True,
            text=True,
        )
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        publish("bank at scale", rows, command, save=not args.no_save)  # after each size: 1M takes long
    return 0


if __name__ == "__main__":
    sys.exit(main())
