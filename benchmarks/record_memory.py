"""Benchmark: peak memory per sample of reading a one-sample-per-line text record (issue 42, item 3).

The worst case of the plain-text reader: a record of one short value a line (``0.012\\n``: a few bytes a
sample). Measured in one process with ``tracemalloc`` (numpy's arrays are traced too), for the same file:

1. ``new``: `rig.records.text.read_text` as it is (numpy's reader, no Python object per line);
2. ``old``: the way it read before: the file split into a list of lines, each split into tokens, each parsed into a
   Python float, then the array (the loop below is that reader's, without its checks).

Usage: ``python benchmarks/record_memory.py [--samples N]``; prints one JSON object: ``bytes_per_sample`` of each,
their ratio, the goal (32 bytes per sample) and whether the new reader meets it.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from rig.records.source import read_source
from rig.records.text import read_text

GOAL_BYTES_PER_SAMPLE = 32.0


def _old_way(path: Path) -> np.ndarray:
    src = read_source(path, "samples")
    rows = [(n, line.split()) for n, line in enumerate(src.lines, 1) if line.strip() and not line.startswith("#")]
    return np.array([float(tokens[-1]) for _, tokens in rows])


def _peak(read: object, path: Path) -> tuple[int, float]:
    tracemalloc.start()
    tracemalloc.reset_peak()
    t0 = time.perf_counter()
    result = read(path)  # type: ignore[operator]
    seconds = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    del result
    return peak, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2_000_000, help="samples in the record (default 2,000,000)")
    args = parser.parse_args()
    rng = np.random.default_rng(42)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "long.txt"
        values = np.round(rng.normal(0.0, 0.02, args.samples), 3)
        with open(path, "w") as f:
            f.write("# dt = 0.0005 s\n# units = g\n")
            f.write("\n".join(f"{v:g}" for v in values))
            f.write("\n")
        size = path.stat().st_size
        new_peak, new_s = _peak(lambda p: read_text(p).acc_h, path)
        old_peak, old_s = _peak(_old_way, path)
    new, old = new_peak / args.samples, old_peak / args.samples
    print(json.dumps({
        "samples": args.samples, "file_bytes": size, "unit": "bytes per sample (tracemalloc peak / samples)",
        "bytes_per_sample": {"new": round(new, 2), "old": round(old, 2)}, "old_over_new": round(old / new, 1),
        "seconds": {"new": round(new_s, 3), "old": round(old_s, 3)},
        "goal_bytes_per_sample": GOAL_BYTES_PER_SAMPLE, "goal_met": new <= GOAL_BYTES_PER_SAMPLE,
    }))


if __name__ == "__main__":
    main()
