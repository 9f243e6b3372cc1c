"""Cost of the integrity checks: cached folder load and BVH parse, this checkout against a reference commit.

Run: ``python bench/integrity.py [--data DIR] [--reference REV] [--rounds 5]``. The reference commit is
checked out into a temporary git worktree; both trees are timed in alternating subprocesses (one round
= one run of each), so the machine's load drifts over both alike, and the best of the rounds is compared
(on a shared machine the load only ever adds time). Target: neither slower by over 10 %.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "bandai-namco-2"
#: The last commit before the integrity work (issue 13): what "before" means in the table.
DEFAULT_REFERENCE = "69b2202"

#: Times the reference's datasets.py and this one alternately in one process (both on this tree's Motion,
#: formats and cache folder), which isolates the cache and reading changes from the rest of the tree.
_SAME_PROCESS = """
import importlib.util, json, sys, time
sys.path.insert(0, sys.argv[1])
spec = importlib.util.spec_from_file_location("reference_datasets", sys.argv[3])
reference = importlib.util.module_from_spec(spec)
sys.modules["reference_datasets"] = reference
spec.loader.exec_module(reference)
from engine.motion import datasets
data, rounds = sys.argv[2], int(sys.argv[4])
reference.load_folder(data)
datasets.load_folder(data)
times = {"reference": [], "this": []}
for _ in range(rounds):
    for name, module in (("reference", reference), ("this", datasets)):
        start = time.perf_counter()
        module.load_folder(data)
        times[name].append(time.perf_counter() - start)
print(json.dumps(times))
"""

_WORKER = """
import json, statistics, sys, time
sys.path.insert(0, sys.argv[1])
import engine
assert engine.__file__.startswith(sys.argv[1]), engine.__file__
from pathlib import Path
from engine.motion.bvh import read_bvh
from engine.motion.datasets import load_folder
data = Path(sys.argv[2])
load_folder(data)  # builds this tree's cache when it has none
start = time.perf_counter()
n = len(load_folder(data))
cached = time.perf_counter() - start
files = sorted((data / "data").glob("*.bvh"))[:: max(1, 2902 // int(sys.argv[3]))]
reads = []
for path in files:
    start = time.perf_counter()
    read_bvh(path)
    reads.append(time.perf_counter() - start)
print(json.dumps({"clips": n, "cached_s": cached, "bvh_ms": 1000 * statistics.median(reads)}))
"""


def _run(tree: Path, data: Path, files: int) -> dict[str, float]:
    """One timing run of ``tree``'s engine in a fresh process."""
    out = subprocess.run(
        [sys.executable, "-c", _WORKER, str(tree), str(data), str(files)],
        capture_output=True,
        text=True,
        check=True,
        env=os.environ | {"PYTHONPATH": str(tree)},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    """Time both trees and record the ``integrity`` section of docs/BENCHMARKS.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(os.environ.get("ODMO_BANDAI2") or DEFAULT_DATA))
    parser.add_argument("--reference", default=DEFAULT_REFERENCE, help="git revision to compare against")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--files", type=int, default=100, help="BVH files parsed per run")
    parser.add_argument("--no-record", action="store_true", help="print only, leave docs/BENCHMARKS.md")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        reference = Path(tmp) / "reference"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(reference), args.reference],
            check=True,
            capture_output=True,
        )
        try:
            runs: dict[str, list[dict[str, float]]] = {"reference": [], "this": []}
            for _ in range(args.rounds):
                runs["reference"].append(_run(reference, args.data, args.files))
                runs["this"].append(_run(ROOT, args.data, args.files))
            command = [sys.executable, "-c", _SAME_PROCESS, str(ROOT), str(args.data)]
            command += [str(reference / "engine" / "motion" / "datasets.py"), str(args.rounds)]
            out = subprocess.run(command, capture_output=True, text=True, check=True)
            same_process = json.loads(out.stdout.strip().splitlines()[-1])
        finally:
            remove = ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(reference)]
            subprocess.run(remove, check=True)

    def best(tree: str, key: str) -> float:
        return min(run[key] for run in runs[tree])

    def median(tree: str, key: str) -> float:
        return statistics.median(run[key] for run in runs[tree])

    n = int(runs["this"][0]["clips"])
    rows = []
    for key, measure, unit in (
        ("cached_s", f"load folder, {n} files, cached", "s"),
        ("bvh_ms", f"read BVH, median of {args.files} files", "ms"),
    ):
        before, after = best("reference", key), best("this", key)
        spread = f"median {median('reference', key):.4g} → {median('this', key):.4g}"
        rows.append({"measure": f"{measure}: reference {args.reference}", "value": before, "unit": unit})
        rows.append(
            {
                "measure": f"{measure}: this checkout",
                "value": after,
                "unit": unit,
                "target": f"ratio {after / before:.3f} (≤ 1.10); {spread}",
            }
        )
    before, after = min(same_process["reference"]), min(same_process["this"])
    measure = f"load folder, {n} files, cached, datasets.py alone in one process"
    rows.append({"measure": f"{measure}: reference {args.reference}", "value": before, "unit": "s"})
    spread = f"median {statistics.median(same_process['reference']):.4g} → "
    spread += f"{statistics.median(same_process['this']):.4g}"
    rows.append(
        {
            "measure": f"{measure}: this checkout",
            "value": after,
            "unit": "s",
            "target": f"ratio {after / before:.3f} (≤ 1.10); {spread}",
        }
    )
    for row in rows:
        print(f"{row['measure']}: {row['value']:.4g} {row['unit']} {row.get('target', '')}")
    if not args.no_record:
        record("integrity", rows, f"python bench/integrity.py --rounds {args.rounds} --files {args.files}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
