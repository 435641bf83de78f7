"""Benchmark: ``rig report`` generation time for the paper-style campaign and for a paper-size study.

Prints one JSON object:

* ``session``: a session file of the paper's experimental campaign size — 125 runs (25 records × 5 angles, Table
  VI), 7 bodies on the plate (Table V), a ~60 s drive per run with its commanded trajectory at 1 kHz and one plate
  accelerometer at 1 kHz, detections, and the ``analysis`` datasets of ``rig analyze`` (predictions per run, the
  Fig. 13 table) — synthesised with the real session writer (`rig.session.SessionLog`: band-limited, enveloped
  random motion, not real records); then `rig.report.write_report` on it: ``report_seconds`` (median of
  ``--repeat``), the output size, figures, and the time per run;
* ``study``: a study file of the paper's analytical size — 12 bodies (Table I), 314 records, both signs, 15 angles
  (0–7°) — synthesised in the agreed layout (COR from Eq. 13 with noise, the real fits of `analysis.design` and
  Table III estimators), and its report time.

Usage: ``python benchmarks/report.py [--runs 125] [--seconds 60] [--repeat 1] [--dir DIR] [--keep]``.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
from scipy import signal

from analysis import TABLE_I, TABLE_V
from analysis.body import G
from analysis.design import fit_gcor, fit_scor, scor, table3_estimators
from rig.report import write_report
from rig.session import SessionLog

RATE = 1000.0  # [Hz] commanded trajectory and accelerometer
ANGLES = (0.0, 4.0, 4.5, 5.0, 5.5)  # [deg] the paper's campaign
MODELS = (b"rocking", b"general")


def _motion(rng: np.random.Generator, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, surge [m], surge acceleration [m/s²]): 0.3–8 Hz random motion with a 2 s taper, peak ~3 m/s²."""
    t = np.arange(0.0, seconds, 1.0 / RATE)
    sos = signal.butter(4, (0.3, 8.0), "bandpass", fs=RATE, output="sos")
    acc = signal.sosfiltfilt(sos, rng.normal(size=t.size))
    taper = np.clip(np.minimum(t, seconds - t) / 2.0, 0.0, 1.0)
    acc *= taper * 3.0 / np.max(np.abs(acc))
    vel = np.cumsum(acc) / RATE
    vel -= np.linspace(0.0, vel[-1], vel.size)
    disp = np.cumsum(vel) / RATE
    disp -= np.linspace(0.0, disp[-1], disp.size)
    return t, disp, np.gradient(np.gradient(disp, t), t)


def make_campaign(path: Path, runs: int, seconds: float) -> None:
    """The synthetic campaign session (module docstring)."""
    rng = np.random.default_rng(7)
    bodies = [{"body_id": i + 1, "name": f"Table V body {i + 1}", "b": b.b, "h": b.h, "depth": 2.2 * b.b,
               "mass": 1.0, "x": 0.0, "y": -0.45 + 0.15 * i} for i, b in enumerate(TABLE_V[:7])]
    records = [f"fema:RECORD{k:02d}" for k in range(25)]
    sequence = {"name": "paper campaign (synthetic)", "description": "125 runs, 7 bodies", "angles_deg": list(ANGLES),
                "repetitions": 1, "records": [{"record": r, "scale": "table"} for r in records], "bodies": bodies,
                "drive": {"settle_s": 0.5}, "operator": {"confirm_before_run": True, "ask_detections": False}}
    rig = {"table": {"controller_rate_hz": RATE}, "limits": {
        "surge": {"displacement_m": 0.25, "velocity_m_s": 0.8, "acceleration_m_s2": 14.7}}}
    with SessionLog.create(path, rig, sequence, "benchmark") as log:
        for k in range(runs):
            angle = ANGLES[k // 25 % len(ANGLES)]
            beta = math.radians(angle)
            t, disp, acc = _motion(rng, seconds)
            commanded = np.zeros((t.size, 7))
            commanded[:, 0], commanded[:, 1], commanded[:, 5] = t, disp, beta
            run = log.begin_run(k, record=records[k % 25], scale_factor=float(rng.uniform(0.3, 1.0)), angle_deg=angle,
                                commanded=commanded, bodies=bodies, sensors=["0"],
                                attrs={"governing_axis": "surge", "governing_quantity": "displacement",
                                       "corner_frequency": 0.2, "table_url": "benchmark"})
            force = np.column_stack([acc * math.cos(beta) - G * math.sin(beta), np.zeros_like(acc),
                                     acc * math.sin(beta) + G * math.cos(beta)])
            run.append_accel("0", t, force + rng.normal(0.0, 0.02, force.shape))
            for body in bodies:
                if rng.random() < 0.6:
                    run.add_detection(float(rng.uniform(5, seconds - 5)), body["body_id"],
                                      1 if rng.random() < 0.9 else -1, "sensor")
            run.end("completed", underruns=0, t_start_controller_ns=0)
    pred = np.dtype([("body_id", "<i4"), ("model", "S16"), ("direction", "i1"), ("t_overturn", "<f8"),
                     ("theta_max", "<f8"), ("observed", "i1")])
    fig13 = np.dtype([("angle_deg", "<f8"), ("body_id", "<i4"), ("model", "S16"), ("runs", "<i4"),
                      ("overturned_analysis", "<i4"), ("towards_low_analysis", "<i4"), ("cor_analysis", "<f8"),
                      ("overturned_experiment", "<i4"), ("towards_low_experiment", "<i4"),
                      ("cor_experiment", "<f8"), ("difference", "<f8")])
    with h5py.File(path, "r+", locking=False) as h5:
        for name in h5["runs"]:
            rows = [(b["body_id"], m, 1, 10.0, 1.6, 1) for b in bodies for m in MODELS]
            h5["runs"][name].create_group("analysis").create_dataset("predictions", data=np.array(rows, pred))
        rows = []
        for angle in ANGLES:
            for body_id in range(8):
                for m in MODELS:
                    cor_a, cor_e = float(rng.uniform(0.5, 1.0)), float(rng.uniform(0.5, 1.0))
                    rows.append((angle, body_id, m, 25, 20, round(20 * cor_a), cor_a, 20, round(20 * cor_e), cor_e,
                                 cor_a - cor_e))
        group = h5.create_group("analysis")
        group.create_dataset("fig13", data=np.array(rows, fig13))
        for m in MODELS:
            group.attrs[f"max_difference_{m.decode()}"] = 0.05


def make_study(path: Path) -> None:
    """A paper-size study file (module docstring)."""
    rng = np.random.default_rng(11)
    angles = np.radians(np.arange(0.0, 7.01, 0.5))
    bodies = list(TABLE_I)
    cor_rows, fit_rows = [], []
    per_body = []
    for j, b in enumerate(bodies):
        cor = np.clip(np.asarray(scor(angles, b)) + rng.normal(0, 0.03, angles.size), 0.0, 1.0)
        per_body.append(cor)
        for a, c in zip(angles, cor, strict=True):
            cor_rows.append((j, math.degrees(a), 600, round(600 * c), c))
            fit_rows.append((b.b, b.h, a, c, 600))
    avg = np.mean(per_body, axis=0)
    cor_rows += [(-1, math.degrees(a), 7200, round(7200 * c), c) for a, c in zip(angles, avg, strict=True)]
    gfit, sfit = fit_gcor(angles, avg), fit_scor(fit_rows)
    est = []
    for j, b in enumerate(bodies):
        for eq, fitted in ((b"GCOR", gfit.c2 * np.tanh(angles / gfit.c1) + 0.5),
                           (b"SCOR", np.asarray(scor(angles, b, sfit.coeffs[:3], sfit.c2)))):
            e = table3_estimators(angles, per_body[j], fitted)
            est.append((j, eq, e["max_difference"], e["absolute_area"], e["error"]))
    cor_dt = np.dtype([("body_index", "<i4"), ("angle_deg", "<f8"), ("overturned", "<i4"), ("desired", "<i4"),
                       ("cor", "<f8")])
    est_dt = np.dtype([("body_index", "<i4"), ("equation", "S8"), ("max_difference", "<f8"),
                       ("absolute_area", "<f8"), ("error", "<f8")])
    with h5py.File(path, "w") as h5:
        h5.attrs.update({"schema": "shaketable-rig/study/1", "software_version": "benchmark", "created": "now",
                         "model": "rocking", "restitution": "0", "friction": 1.0,
                         "records": json.dumps([f"fema:RECORD{k:03d}" for k in range(314)]),
                         "bodies": json.dumps([{"b": b.b, "h": b.h, "name": str(j + 1)} for j, b in enumerate(bodies)]),
                         "angles_deg": np.degrees(angles), "seconds": 100.0, "scenes": 12 * 314 * 2 * 15,
                         "where": "synthetic", "summary": json.dumps({"where": "synthetic"}),
                         "signs": np.array([1, -1], np.int8)})
        h5.create_dataset("direction", data=rng.choice(np.array([-1, 0, 1], np.int8), (12, 314, 2, angles.size)))
        h5.create_dataset("cor", data=np.array(cor_rows, cor_dt))
        h5.create_dataset("estimators", data=np.array(est, est_dt))
        g = h5.create_group("fits/gcor")
        g.attrs.update({"c1": gfit.c1, "c2": gfit.c2, "c1_ci_low": gfit.c1_ci[0], "c1_ci_high": gfit.c1_ci[1]})
        s = h5.create_group("fits/scor")
        s.attrs.update(dict(zip(("k1", "k2", "k3", "c2"), sfit.coeffs, strict=True)))


def _time(source: Path, output: Path, repeat: int) -> tuple[float, dict[str, object]]:
    times, result = [], None
    for _ in range(repeat):
        result = write_report(source, output)
        times.append(result.seconds)
    assert result is not None
    return statistics.median(times), result.as_dict()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=125)
    parser.add_argument("--seconds", type=float, default=60.0, help="drive length per run [s]")
    parser.add_argument("--repeat", type=int, default=1, help="report generations per file (median reported)")
    parser.add_argument("--dir", type=Path, default=None, help="where the files go (default: a temporary dir)")
    parser.add_argument("--keep", action="store_true", help="keep the files")
    args = parser.parse_args()
    work = args.dir or Path(tempfile.mkdtemp(prefix="report-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        session = work / "campaign.h5"
        synth = None
        if not session.exists():
            t0 = time.perf_counter()
            make_campaign(session, args.runs, args.seconds)
            synth = round(time.perf_counter() - t0, 1)
        seconds, result = _time(session, work / "campaign.html", args.repeat)
        study_file = work / "study.h5"
        if not study_file.exists():
            make_study(study_file)
        study_seconds, study_result = _time(study_file, work / "study.html", args.repeat)
        out = {
            "figure": "report generation time, paper-style campaign session", "value": round(seconds, 2), "unit": "s",
            "session": {"runs": args.runs, "bodies": 7, "drive_seconds": args.seconds, "rate_hz": RATE,
                        "file_bytes": session.stat().st_size, "synthesis_seconds": synth,
                        "report_seconds": round(seconds, 2), "per_run_ms": round(1000 * seconds / args.runs, 1),
                        "report": result},
            "study": {"bodies": 12, "records": 314, "angles": 15, "file_bytes": study_file.stat().st_size,
                      "report_seconds": round(study_seconds, 3), "report": study_result},
            "repeat": args.repeat,
        }
        print(json.dumps(out))
    finally:
        if args.dir is None and not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
