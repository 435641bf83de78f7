"""Benchmark: peak memory per sample of reading a long record, per format (issue 42, item 3).

Each format's usual case: the plain-text reader on one short value a line (``0.012\\n``: a few bytes a sample,
its worst case), the PEER ``.AT2`` reader on NGA-West2's five values of 15 characters a line, the CSV reader on
``time_s,acc_g`` rows (``csv``: 16 bytes a row, held while the rows are parsed into two float64 columns, so about
32 bytes a sample whatever the reader does) and on one ``acc_g`` column with a ``# dt`` line (``csv1``), the
COSMOS reader on one channel in Format=(5E15.6) (``cosmos``: its values are still parsed one field at a time, from
lines decoded one at a time).
Measured in one process with ``tracemalloc`` (numpy's arrays are traced too), for the same file:

1. ``new``: the reader as it is (`rig.records.text.read_text`, `rig.records.peer.read_at2`,
   `rig.records.csvfile.read_csv`, `rig.records.cosmos.read_cosmos`: no Python object kept per sample);
2. ``old``: the way they read before: the file split into a list of lines, each split into tokens, each parsed into
   a Python float, then the array (the loops below are those readers', without their checks).

Usage: ``python benchmarks/record_memory.py [--samples N] [--format text|at2|csv|csv1|cosmos ...]``; prints one JSON
object per format: ``bytes_per_sample`` of each, their ratio, the goal (32 bytes per sample) and whether the new
reader meets it.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import tracemalloc
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig.records import RecordWarning
from rig.records.cosmos import read_cosmos
from rig.records.csvfile import read_csv
from rig.records.peer import read_at2
from rig.records.source import read_source
from rig.records.text import read_text

GOAL_BYTES_PER_SAMPLE = 32.0


def _write_text(path: Path, values: np.ndarray) -> None:
    with open(path, "w") as f:
        f.write("# dt = 0.0005 s\n# units = g\n")
        f.write("\n".join(f"{v:g}" for v in np.round(values, 3)))
        f.write("\n")


def _old_text(path: Path) -> np.ndarray:
    src = read_source(path, "samples")
    rows = [(n, line.split()) for n, line in enumerate(src.lines, 1) if line.strip() and not line.startswith("#")]
    return np.array([float(tokens[-1]) for _, tokens in rows])


def _write_at2(path: Path, values: np.ndarray) -> None:
    rows = [" ".join(f"{v:15.7E}" for v in values[i:i + 5]) for i in range(0, values.size, 5)]
    header = ["PEER NGA STRONG MOTION DATABASE RECORD", "Benchmark, 1/1/2000, Station, H1",
              "ACCELERATION TIME SERIES IN UNITS OF G", f"NPTS= {values.size}, DT= .0050 SEC"]
    path.write_text("\n".join(header + rows) + "\n")


def _write_csv(path: Path, values: np.ndarray) -> None:
    rows = "".join(f"{i * 0.005:.3f},{v:g}\n" for i, v in enumerate(np.round(values, 4)))
    path.write_text("time_s,acc_g\n" + rows)


def _write_csv1(path: Path, values: np.ndarray) -> None:
    path.write_text("# dt = 0.005 s\nacc_g\n" + "".join(f"{v:g}\n" for v in np.round(values, 4)))


def _old_csv(path: Path) -> dict[str, np.ndarray]:
    src = read_source(path, "samples")
    rows = [(n, line.split(",")) for n, line in enumerate(src.lines, 1) if line.strip() and not line.startswith("#")]
    channels: list[list[float]] = [[] for _ in rows[0][1]]
    for _, cells in rows[1:]:
        for channel, cell in zip(channels, cells, strict=True):
            channel.append(float(cell.strip()))
    return {str(i): np.array(channel) for i, channel in enumerate(channels)}


def _write_cosmos(path: Path, values: np.ndarray) -> None:
    sine = Path(__file__).parents[1] / "tests" / "data" / "records" / "cosmos_sine.V2"
    lines = sine.read_text().splitlines()
    rows = ["".join(f"{v:15.6e}" for v in values[i:i + 5]) for i in range(0, values.size, 5)]
    data_header = lines[48].replace("      22", f"{values.size:8d}")
    path.write_text("\n".join([*lines[:48], data_header, *rows, lines[-1]]) + "\n")


def _old_cosmos(path: Path) -> np.ndarray:
    src = read_source(path, "samples")
    values = [float(line[i:i + 15]) for line in src.lines[49:-1] for i in range(0, len(line), 15)]
    return np.asarray(values, dtype=np.float64)


def _old_at2(path: Path) -> np.ndarray:
    src = read_source(path, "samples")
    values = [float(token) for line in src.lines[4:] for token in line.split()]
    return np.asarray(values, dtype=np.float64)


#: format: (file name, writer, new reader, old reader)
FORMATS: dict[str, tuple[str, Callable[[Path, np.ndarray], None], Callable[[Path], object],
                         Callable[[Path], object]]] = {
    "text": ("long.txt", _write_text, lambda p: read_text(p).acc_h, _old_text),
    "at2": ("long.AT2", _write_at2, lambda p: read_at2(p).acc_h, _old_at2),
    "csv": ("long.csv", _write_csv, lambda p: read_csv(p).acc_h, _old_csv),
    "csv1": ("long.csv", _write_csv1, lambda p: read_csv(p).acc_h, _old_csv),
    "cosmos": ("long.V2", _write_cosmos, lambda p: read_cosmos(p).acc_h, _old_cosmos),
}


def _peak(read: Callable[[Path], object], path: Path) -> tuple[int, float]:
    tracemalloc.start()
    tracemalloc.reset_peak()
    t0 = time.perf_counter()
    result = read(path)
    seconds = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    del result
    return peak, seconds


def measure(fmt: str, samples: int, tmp: Path) -> dict[str, object]:
    """Peak bytes per sample and seconds of the new and the old reader of ``fmt`` on one file of ``samples``."""
    name, write, new_read, old_read = FORMATS[fmt]
    path = tmp / name
    write(path, np.random.default_rng(42).normal(0.0, 0.02, samples))
    size = path.stat().st_size
    new_peak, new_s = _peak(new_read, path)
    old_peak, old_s = _peak(old_read, path)
    path.unlink()
    new, old = new_peak / samples, old_peak / samples
    return {
        "format": fmt, "samples": samples, "file_bytes": size,
        "unit": "bytes per sample (tracemalloc peak / samples)",
        "bytes_per_sample": {"new": round(new, 2), "old": round(old, 2)}, "old_over_new": round(old / new, 1),
        "seconds": {"new": round(new_s, 3), "old": round(old_s, 3)},
        "goal_bytes_per_sample": GOAL_BYTES_PER_SAMPLE, "goal_met": new <= GOAL_BYTES_PER_SAMPLE,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2_000_000, help="samples in the record (default 2,000,000)")
    parser.add_argument("--format", action="append", choices=sorted(FORMATS), help="a format (default: all)")
    args = parser.parse_args()
    warnings.simplefilter("ignore", RecordWarning)  # the benchmark files name no component
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in args.format or list(FORMATS):
            print(json.dumps(measure(fmt, args.samples, Path(tmp))))


if __name__ == "__main__":
    main()
