"""Latent-bank timings: GMM + silhouette mode selection and 2D map fits on synthetic 20-D clustered codes.

Run: ``nice python bench/latent.py [--sizes 1000 3000 10000] [--threads 1]``. For each size N, one action of
N codes drawn from 6 Gaussian clusters: ``discover_modes`` over K = 3..11, then PCA / t-SNE / UMAP fits, and
the per-query cost of the interactive calls (inverse of one map point, end location of one code).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _threads(n: int) -> None:
    """Limit BLAS / OpenMP / numba threads (must run before numpy is imported)."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = str(n)


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
    args = parser.parse_args(argv)
    _threads(args.threads)

    import numpy as np

    from engine.latent.bank import LatentBank
    from engine.latent.modes import discover_modes
    from engine.latent.projection import make_projection

    rows = []
    for n in args.sizes:
        rng = np.random.default_rng(n)
        centers = rng.normal(0.0, 3.0, (6, args.dim))
        labels = rng.integers(0, len(centers), n)
        codes = (centers[labels] + rng.normal(0.0, 1.0, (n, args.dim))).astype(np.float32)
        seconds, modes = _seconds(lambda codes=codes: discover_modes(codes, k_range=(3, 11), seed=0))
        rows.append(
            {
                "N": n,
                "step": "discover_modes, K = 3..11 (one action)",
                "s": round(seconds, 2),
                "note": f"K chosen {modes.k_chosen}, {modes.n_modes} kept (6 planted)",
            }
        )
        print(rows[-1], flush=True)
        for name in ("pca", "tsne", "umap"):
            seconds, projection = _seconds(lambda name=name, codes=codes: make_projection(name).fit(codes))
            query = projection.embedding_[:1] + 0.01
            per_query, _ = _seconds(lambda p=projection, q=query: [p.inverse_transform(q) for _ in range(20)])
            rows.append(
                {
                    "N": n,
                    "step": f"{name} fit",
                    "s": round(seconds, 2),
                    "note": f"inverse of one point {per_query / 20 * 1e3:.2f} ms (fitted model)",
                }
            )
            print(rows[-1], flush=True)
        bank = LatentBank(
            codes,
            np.zeros(n, dtype=np.int64),
            ["a"],
            rng.normal(size=(n, 3)).astype(np.float32),
            np.full(n, "", dtype=np.str_),
            [{}] * n,
        )
        per_query, _ = _seconds(lambda b=bank, c=codes[:1] + 0.01: [b.end_location(c, 0) for _ in range(100)])
        rows.append(
            {
                "N": n,
                "step": "end_location, one code (k = 8)",
                "s": round(per_query / 100, 5),
                "note": f"{per_query / 100 * 1e3:.2f} ms",
            }
        )
        print(rows[-1], flush=True)

    # Imported last so that the measurements above still print where the report helper is missing.
    from bench._report import record

    sizes = " ".join(str(s) for s in args.sizes)
    record("latent", rows, f"nice python bench/latent.py --sizes {sizes} --threads {args.threads}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
