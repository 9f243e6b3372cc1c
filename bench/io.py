"""Motion I/O timings on the Bandai-Namco-2 folder: per-file BVH read, folder load cold and cached, writes.

Run: ``python bench/io.py [--data DIR] [--files 50] [--limit N]``. Targets: reading a 200-frame BVH
< 20 ms; loading the whole cached folder (2,902 files) < 5 s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record
from engine.motion.bvh import read_bvh, write_bvh
from engine.motion.datasets import load_folder
from engine.motion.npz import write_npz

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "bandai-namco-2"


def _median_ms(times: list[float]) -> float:
    """Median of ``times`` (seconds) in milliseconds."""
    return 1000.0 * statistics.median(times)


def _timed(func, *args) -> float:
    """Seconds one call of ``func(*args)`` takes."""
    start = time.perf_counter()
    func(*args)
    return time.perf_counter() - start


def main() -> int:
    """Run the benchmark and record the ``io`` section of docs/BENCHMARKS.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(os.environ.get("ODMO_BANDAI2") or DEFAULT_DATA))
    parser.add_argument("--files", type=int, default=50, help="files timed one by one")
    parser.add_argument("--limit", type=int, help="load only this many files of the folder")
    parser.add_argument("--no-record", action="store_true", help="print only, leave docs/BENCHMARKS.md")
    args = parser.parse_args()

    files = sorted((args.data / "data").glob("*.bvh"))
    step = max(1, len(files) // args.files)
    sample = files[::step][: args.files]
    reads = {path: _timed(read_bvh, path) for path in sample}
    frames = {path: read_bvh(path).n_frames for path in sample}
    near_200 = sorted(sample, key=lambda p: abs(frames[p] - 200))[:10]
    typical = statistics.median(frames.values())
    rows = [
        {
            "measure": f"read BVH, median of {len(sample)} files (median {typical:g} frames)",
            "value": _median_ms(list(reads.values())),
            "unit": "ms",
            "target": "",
        },
        {
            "measure": "read BVH of ~200 frames, median of 10 files",
            "value": _median_ms([reads[p] for p in near_200]),
            "unit": "ms",
            "target": "< 20",
        },
    ]
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["ODMO_CACHE_DIR"] = str(Path(tmp) / "cache")
        cold = _timed(load_folder, args.data, None, None, True, None, None, args.limit)
        start = time.perf_counter()
        dataset = load_folder(args.data, limit=args.limit)
        cached = time.perf_counter() - start
        n = len(dataset)
        rows.append(
            {"measure": f"load folder, {n} files, cold (parse + write cache)", "value": cold, "unit": "s"}
        )
        rows.append(
            {"measure": f"load folder, {n} files, cached", "value": cached, "unit": "s", "target": "< 5"}
        )
        clips = sorted(dataset.clips, key=lambda m: abs(m.n_frames - 200))[:10]
        bvh = [_timed(write_bvh, Path(tmp) / f"{i}.bvh", m) for i, m in enumerate(clips)]
        npz = [_timed(write_npz, Path(tmp) / f"{i}.npz", m) for i, m in enumerate(clips)]
    rows.append(
        {
            "measure": "write BVH of ~200 frames from joints (IK included)",
            "value": _median_ms(bvh),
            "unit": "ms",
        }
    )
    rows.append({"measure": "write NPZ of ~200 frames", "value": _median_ms(npz), "unit": "ms"})
    for row in rows:
        print(f"{row['measure']}: {row['value']:.4g} {row['unit']}")
    if not args.no_record:
        limit = f" --limit {args.limit}" if args.limit else ""
        record("io", rows, f"python bench/io.py --files {args.files}{limit}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
