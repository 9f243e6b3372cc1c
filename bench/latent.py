"""Latent-bank timings: GMM + silhouette mode selection and 2D map fits on synthetic 20-D clustered codes.

Run: ``nice python bench/latent.py [--sizes 1000 3000 10000] [--threads 1]``. For each size N, one action of
N codes drawn from 6 Gaussian clusters: ``ModeModel.fit`` over K = 3..11, then PCA / t-SNE / UMAP fits, and
the steady-state per-query cost of the interactive calls (inverse of one map point, placing one new code,
end location of one code; neighbour lookups are built on the first query and kept). Last, a whole
``build_bank`` on the bundled model's codes (every action's modes and the three maps).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record
from engine.latent.bank import LatentBank, build_bank
from engine.latent.modes import ModeModel
from engine.latent.projection import make_projection

DEFAULT_MODEL = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo"


def _seconds(fn: Callable[[], object]) -> tuple[float, object]:
    """Wall seconds of one call and its result."""
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def main(argv: list[str] | None = None) -> int:
    """Measure and record the latent-bank benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 3000, 10000])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--dim", type=int, default=20)
    parser.add_argument(
        "--bank-of", type=Path, default=DEFAULT_MODEL, help="time a whole bank build on this model's codes"
    )
    args = parser.parse_args(argv)
    with threadpool_limits(args.threads):
        rows = measure(args.sizes, args.dim)
        if (args.bank_of / "latent_bank.npz").is_file():
            rows.append(measure_bank_build(args.bank_of))
    sizes = " ".join(str(s) for s in args.sizes)
    record("latent", rows, f"nice python bench/latent.py --sizes {sizes} --threads {args.threads}")
    return 0


def measure_bank_build(model_dir: Path) -> dict[str, object]:
    """Seconds of ``build_bank`` (modes of every action, PCA, t-SNE, UMAP) on a model's bank codes."""
    bank = LatentBank.load(model_dir / "latent_bank.npz")
    seconds, _ = _seconds(
        lambda: build_bank(
            bank.codes, bank.actions, bank.ends, bank.sources, bank.meta, bank.action_names, seed=0
        )
    )
    n, k = len(bank.codes), len(bank.action_names)
    row = {"N": n, "step": "build_bank", "s": float(f"{seconds:.3g}")}
    row["note"] = f"{model_dir.name}: {k} actions' modes (K = 3..11), PCA, t-SNE, UMAP"
    print(row, flush=True)
    return row


def measure(sizes: list[int], dim: int) -> list[dict[str, object]]:
    """Timing rows for each number of codes in ``sizes``."""
    # Compile umap's numba code first, so that the timings below are of steady-state use.
    warm = np.random.default_rng(0).normal(size=(100, dim))
    make_projection("umap").fit(warm).transform(warm[:1])

    rows: list[dict[str, object]] = []

    def add(n: int, step: str, seconds: float, note: str) -> None:
        rows.append({"N": n, "step": step, "s": float(f"{seconds:.3g}"), "note": note})
        print(rows[-1], flush=True)

    for n in sizes:
        rng = np.random.default_rng(n)
        centers = rng.normal(0.0, 3.0, (6, dim))
        labels = rng.integers(0, len(centers), n)
        codes = (centers[labels] + rng.normal(0.0, 1.0, (n, dim))).astype(np.float32)
        seconds, modes = _seconds(lambda codes=codes: ModeModel(k_range=(3, 11), seed=0).fit(codes))
        add(
            n,
            "ModeModel.fit, K = 3..11",
            seconds,
            f"K chosen {modes.k_chosen_}, {modes.n_modes_} kept (6 planted)",
        )
        probe = codes[:1] + 0.01
        for name in ("pca", "tsne", "umap"):
            seconds, projection = _seconds(lambda name=name, codes=codes: make_projection(name).fit(codes))
            point = projection.embedding_[:1] + 0.01
            projection.inverse_transform(point), projection.transform(probe)  # build the neighbour lookups
            inverse, _ = _seconds(lambda p=projection, q=point: [p.inverse_transform(q) for _ in range(20)])
            forward, _ = _seconds(lambda p=projection, c=probe: [p.transform(c) for _ in range(20)])
            add(
                n,
                f"{name} fit",
                seconds,
                f"per query: inverse {inverse / 20 * 1e3:.2f} ms, transform {forward / 20 * 1e3:.2f} ms",
            )
        bank = LatentBank(
            codes,
            np.zeros(n, dtype=np.int64),
            ["a"],
            rng.normal(size=(n, 3)).astype(np.float32),
            np.full(n, "", dtype=np.str_),
            [{}] * n,
        )
        bank.end_location(probe, 0)  # builds the action's neighbour lookup
        seconds, _ = _seconds(lambda b=bank, c=probe: [b.end_location(c, 0) for _ in range(100)])
        add(n, "end_location, one code (k = 8)", seconds / 100, f"{seconds / 100 * 1e3:.2f} ms")

    return rows


if __name__ == "__main__":
    sys.exit(main())
