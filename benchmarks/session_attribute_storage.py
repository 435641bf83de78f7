"""Benchmark: what the compact attribute storage of the session file's run groups (``rig.session.hdf5props``,
``set_attr_phase_change``) buys, and what it costs a reader that is not HDF5's (pyfive).

Prints one JSON object. For each of the two settings — ``compact`` (the session file's: up to 1000 attributes
in the object header, flag "attribute phase change values stored" set in the header) and ``hdf5_default`` (HDF5's
8 compact / 6 dense: a run group, with its 15-odd attributes, moves them to a fractal heap and a B-tree) — the
same session is written (``--runs`` runs of 1 s of one accelerometer at 1 kHz), and measured in the same run:

* ``commits``: how each run's begin and end were committed (``rig.session.atomic``: ``pages`` = one page
  rewritten in place, ``shadow`` = a whole copy of the file written and renamed over it), and the
  ``end_commit_s`` of the last run (a shadow commit grows with the file);
* ``pyfive``: whether pyfive (if installed) opens the file and reads a run's attributes, and its error if not.

``figure``/``value``/``unit``: the last run's end commit with the default storage, per the compact one's
(the factor the compact storage saves, at ``--runs`` runs).

Usage: ``python benchmarks/session_attribute_storage.py [--runs 40] [--dir DIR]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rig.session import SessionLog, hdf5props

BODY = {"body_id": 1, "b": 0.1, "h": 0.5, "depth": 0.1, "mass": 5.0, "x": 0.0, "y": 0.0}


def _default_plist(*, links: int | None = None, name_len: int = 4) -> h5py.h5p.PropGCID:
    """`hdf5props.group_plist` without ``set_attr_phase_change``: HDF5's default attribute storage."""
    gcpl = _compact_plist(links=links, name_len=name_len)
    gcpl.set_attr_phase_change(8, 6)
    return gcpl


_compact_plist = hdf5props.group_plist


def _session(path: Path, runs: int) -> dict[str, Any]:
    methods: dict[str, int] = {}
    last_end = 0.0
    with SessionLog.create(path, {}, {"name": "bench"}, "bench") as log:
        for k in range(runs):
            run = log.begin_run(k, record="bench:rest", scale_factor=1.0, angle_deg=0.0,
                                commanded=np.zeros((2, 7)), bodies=[BODY], sensors=["0"],
                                attrs={"rate": 1000.0, "record_start": 0.0, "governing_axis": "surge",
                                       "governing_quantity": "displacement", "corner_frequency": 0.1,
                                       "repetition": 1, "table_url": "mavlink://127.0.0.1:1"})
            methods[f"begin:{log.last_commit.method}"] = methods.get(f"begin:{log.last_commit.method}", 0) + 1
            t = np.arange(1000) / 1000.0
            run.append_accel("0", t, np.zeros((1000, 3)))
            run.end("completed")
            methods[f"end:{log.last_commit.method}"] = methods.get(f"end:{log.last_commit.method}", 0) + 1
            last_end = log.last_commit.seconds
    return {"commits": methods, "end_commit_s": last_end, "file_bytes": path.stat().st_size,
            "pyfive": _pyfive(path)}


def _pyfive(path: Path) -> str:
    try:
        import pyfive
    except ImportError:
        return "not installed"
    try:
        with pyfive.File(str(path)) as f:
            return f"read: record = {f['runs']['0001'].attrs['record']!r}"
    except Exception as exc:  # any failure of the foreign reader is the result
        return f"failed: {type(exc).__name__} {exc}".strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--dir", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        compact = _session(Path(tmp) / "compact.h5", args.runs)
        hdf5props.group_plist = _default_plist  # type: ignore[assignment]
        try:
            default = _session(Path(tmp) / "default.h5", args.runs)
        finally:
            hdf5props.group_plist = _compact_plist  # type: ignore[assignment]
    print(json.dumps({"figure": "end-of-run commit, HDF5's default attribute storage per the compact one",
                      "value": default["end_commit_s"] / compact["end_commit_s"], "unit": "x", "runs": args.runs,
                      "compact": compact, "hdf5_default": default}, indent=2))


if __name__ == "__main__":
    main()
