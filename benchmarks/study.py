"""Benchmark of ``rig study`` end to end, on local cores and on a local Dask cluster; prints one JSON object.

Measured in one run on this machine:
* the paper-scale study — 12 Table I bodies × 100 FEMA P695 components × 2 signs × 15 angles 0–7°
  = 36,000 scenes — through the ``rig study`` command's own code (in process, ``--json -o STUDY.h5``):
  loading the records, the study, the summary (fits, Eq. 12, Table III) and the saved file;
  the kernels are loaded (or compiled) by a warm-up first and that time is reported apart;
* the same command with ``--dask`` on a local cluster started here (2 worker processes × 1 thread, on
  127.0.0.1; its start-up and the workers' warm-up are reported apart), and a check that both runs give
  the same directions scene by scene;
* the measured cost per scene, and what it makes of a study of the whole NGA-West2 set (21,540 records ×
  12 bodies × 2 signs × 15 angles = 7,754,400 scenes). A scene's cost grows with its record's length for the
  scenes that rock (a record below Eq. 1's threshold costs one scan), so the figure assumes records of the
  FEMA set's mean length, which is reported; scale it by the ratio of mean lengths for another set.

Usage: ``python benchmarks/study.py [--workers 2] [--out-dir DIR]``
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from rig.cli import app
from rig.records import load_records
from rig.study_file import read_study

NGA_WEST2_RECORDS = 21_540
BODIES, SIGNS, ANGLES = 12, 2, 15
STUDY_ARGS = ["study", "--records", "fema", "--bodies", "table1", "--angles", "0:7:0.5", "--json"]
WARM_ARGS = ["study", "--records", "fema-farfield:NORTHR/MUL009", "--bodies", "table1:1,4", "--angles", "0,5",
             "--json"]


def run_cli(args: list[str]) -> tuple[dict, float]:
    """``rig ARGS`` in process; its JSON output and wall time [s]."""
    t0 = time.perf_counter()
    result = CliRunner().invoke(app, args)
    wall = time.perf_counter() - t0
    if result.exit_code != 0:
        raise RuntimeError(f"rig {' '.join(args)} failed ({result.exit_code}): {result.output[-2000:]}")
    return json.loads(result.stdout), wall


def figures(out: dict, wall: float) -> dict:
    """Wall time, scenes per second and cost per scene of one run."""
    return {"scenes": out["scenes"], "wall_s": round(wall, 3), "scenes_per_s": round(out["scenes"] / wall, 1),
            "seconds_per_scene": wall / out["scenes"], "study_seconds": out["seconds"],
            "study_seconds_note": "local: the kernel alone; dask: shipping, running and gathering every block",
            "other_s": round(wall - out["seconds"], 3), "where": out["where"]}


def extrapolate(per_scene: float) -> dict:
    scenes = NGA_WEST2_RECORDS * BODIES * SIGNS * ANGLES
    return {"scenes": scenes, "seconds": round(per_scene * scenes, 1), "hours": round(per_scene * scenes / 3600, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2, help="Dask worker processes (1 thread each)")
    ap.add_argument("--out-dir", type=Path, default=None, help="where the study files go (default: a temp dir)")
    args = ap.parse_args()
    out_dir = args.out_dir or Path(tempfile.mkdtemp(prefix="study_bench_"))
    out_dir.mkdir(parents=True, exist_ok=True)

    records = load_records("fema")
    n = np.array([rec.acc_h.size for rec in records])
    durations = np.array([rec.acc_h.size * rec.dt for rec in records])
    report: dict = {"benchmark": "rig study end to end", "machine_cores": os.cpu_count(),
                    "study": {"bodies": BODIES, "records": len(records), "signs": SIGNS, "angles": ANGLES,
                              "model": "rocking", "restitution": 0},
                    "records_mean_length": {"samples": round(float(n.mean()), 1),
                                            "seconds": round(float(durations.mean()), 2),
                                            "min_s": round(float(durations.min()), 2),
                                            "max_s": round(float(durations.max()), 2)}}

    _, warm = run_cli(WARM_ARGS)
    local, local_wall = run_cli([*STUDY_ARGS, "-o", str(out_dir / "local.h5")])
    report["warm_up_local_s"] = round(warm, 2)
    report["local"] = figures(local, local_wall)

    from distributed import Client, LocalCluster

    from analysis.study_dask import warm_up

    t0 = time.perf_counter()
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster, set_as_default=False) as client:
        started = time.perf_counter() - t0
        t0 = time.perf_counter()
        warm_up(client)
        warmed = time.perf_counter() - t0
        remote, remote_wall = run_cli([*STUDY_ARGS, "-o", str(out_dir / "dask.h5"), "--dask",
                                       cluster.scheduler_address])
    report["dask"] = {**figures(remote, remote_wall), "workers": args.workers, "threads_per_worker": 1,
                      "cluster_start_s": round(started, 2), "workers_warm_up_s": round(warmed, 2)}
    same = np.array_equal(read_study(out_dir / "local.h5").direction, read_study(out_dir / "dask.h5").direction)
    report["dask_equals_local_scene_by_scene"] = bool(same)
    report["same_summary"] = all(local[k] == remote[k] for k in ("cor", "gcor", "scor", "estimators"))

    report["fits"] = {"gcor": {k: local["gcor"].get(k) for k in ("c1", "c1_ci", "c2", "c2_ci", "eq12_error")},
                      "scor": {k: local["scor"].get(k) for k in ("k1", "k2", "k3", "c2", "ci", "eq12_error")},
                      "paper": local["paper"]}
    pack_bytes = float(np.sum((n + 1) * SIGNS * 2 * 8)) / len(records)
    report["nga_west2_extrapolation"] = {
        "records": NGA_WEST2_RECORDS, "bodies": BODIES, "signs": SIGNS, "angles": ANGLES,
        "local": extrapolate(report["local"]["seconds_per_scene"]),
        "dask": extrapolate(report["dask"]["seconds_per_scene"]),
        "assumption": (f"records of the FEMA set's mean length ({durations.mean():.1f} s, {n.mean():.0f} samples): "
                       "the cost of a scene that rocks grows with its record's length, so scale by the ratio of "
                       "the two sets' mean lengths (and of their shares of records strong enough to rock the bodies)"),
        "local_packed_records_gb": round(pack_bytes * NGA_WEST2_RECORDS / 1e9, 2),
        "memory_note": "the local path packs every record once per sign with a vertical channel (float64) in one "
                       "array; the Dask path holds one block of records per task",
    }
    report["out_dir"] = str(out_dir)
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
