"""Benchmark of the analysis engines; prints one JSON object.

Measured in one run on this machine:
* the paper-scale study — 12 Table I bodies × 100 FEMA P695 components × 2 signs × 15 angles 0–7°
  = 36,000 scenes — wall time per model with all cores (compilation excluded, warmed up first);
* the reference solver's time per scene on a seeded random sample of the same scenes, hence the
  speed-up per scene;
* accuracy: fast against reference scene by scene on the agreement set (all 100 components × both
  signs × 12 bodies at 0°, 3°, 5°, 7°; ``--quick`` uses a subset), every differing scene listed with
  its chaos check;
* run time against error for several fast-engine steps (p·h) on a sample of scenes that rock;
* the skipping: scenes settled by Eq. 1's pre-screen alone and the integration they did not need;
* the study's body-averaged COR beside the paper's Table II (Eq. 11) and the fitted c1 beside 0.048;
* general model, the stressed agreement set: μ uniform in 0.1–0.6, a vertical input in half of the
  scenes (peak 0.3–1.5 g), either sign, β in 0–10° (600 scenes, ``--quick`` 100): outcome agreement
  with the chaos check, slide displacement and overturn time errors (``verification.compare_stressed``);
* energy added by the fast engine over 60 s of free rocking with e = 1, per step p·h (the bound
  stated in tests/analysis/test_general.py, ``ENERGY_BOUND``).

With ``--baseline DIR`` (a checkout of the code to compare with, e.g. a worktree of main), the paper-scale
study is also timed from DIR's code and from this one alternately, ``--repeats`` times each, each run in its own
process (warmed up first), in the same run of this script: the medians and the speed-up are reported
(``paper_scale_study_vs_baseline``), so that both figures see the same load, with how the two codes' outputs
differ scene by scene.

Usage: ``python benchmarks/engine.py [--quick] [--models rocking,general] [--baseline DIR [--repeats N]]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from analysis import TABLE_I, simulate
from analysis.body import Body
from analysis.design import gcor
from analysis.study import StudyResult, study
from analysis.verification import (
    Agreement,
    compare_stressed,
    compare_with_reference,
    free_rocking_energy_growth,
    stressed_scenes,
)
from rig.records import load_records

ANGLES = np.radians(np.arange(0.0, 7.0 + 1e-9, 0.5))
AGREEMENT_ANGLES = np.radians([0.0, 3.0, 5.0, 7.0])
PAPER_TABLE_II = [50, 59, 67, 75, 81, 85, 89, 92, 94, 95, 96, 97, 97, 97, 98]
STEPS = [0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625]


HERE = Path(__file__).resolve().parents[1]
TIMED_STUDY = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from analysis import TABLE_I
from analysis.study import study
from rig.records import load_records
angles = np.radians(np.arange(0.0, 7.0 + 1e-9, 0.5))
records = load_records("fema")
study(TABLE_I[:2], records[:2], angles[:2], model=sys.argv[2])
cpu = time.process_time()
res = study(TABLE_I, records, angles, model=sys.argv[2])
cpu = time.process_time() - cpu
np.savez(sys.argv[3], direction=res.direction, status=res.status, t_overturn=res.t_overturn,
         theta_max=res.theta_max, steps=res.steps, impacts=res.impacts)
print(json.dumps({"wall_s": res.seconds, "cpu_s": cpu, "rk4_steps": int(res.steps.sum()), "scenes": res.scenes}))
"""


def timed_study(code: Path, model: str, outputs: Path) -> dict:
    """The paper-scale study's wall time [s] and RK4 steps with the code at ``code``, in a fresh process; its
    per-scene outputs go to ``outputs`` (.npz)."""
    out = subprocess.run([sys.executable, "-c", TIMED_STUDY, str(code), model, str(outputs)], check=True,
                         capture_output=True, text=True, cwd=code)
    return json.loads(out.stdout.strip().splitlines()[-1])


def output_differences(a: Path, b: Path) -> dict:
    """How two runs of the paper-scale study differ scene by scene (direction, status, overturn time [s],
    largest rotation [rad] of the scenes that both leave at rest, steps, impacts)."""
    x, y = np.load(a), np.load(b)
    both = (x["status"] == 1) & (y["status"] == 1)
    rest = (x["status"] == 0) & (y["status"] == 0)
    return {"scenes_other_direction": int(np.count_nonzero(x["direction"] != y["direction"])),
            "scenes_other_status": int(np.count_nonzero(x["status"] != y["status"])),
            "t_overturn_max_difference_s": float(np.max(np.abs(x["t_overturn"][both] - y["t_overturn"][both]),
                                                        initial=0.0)),
            "theta_max_max_difference_rad_at_rest": float(np.max(np.abs(x["theta_max"][rest] - y["theta_max"][rest]),
                                                                 initial=0.0)),
            "scenes_other_steps": int(np.count_nonzero(x["steps"] != y["steps"])),
            "scenes_other_impacts": int(np.count_nonzero(x["impacts"] != y["impacts"]))}


def versus_baseline(model: str, baseline: Path, repeats: int) -> dict:
    """The paper-scale study timed with this code and with ``baseline``'s, alternately ``repeats`` times each
    (same load on both): medians [s], every run, and the speed-up (baseline median over this median); the same for
    the CPU time of all the study's threads [s], the fairer figure on a machine that other work keeps busy (a
    thread that waits for a core does not count)."""
    runs: dict[str, list[dict]] = {"this": [], "baseline": []}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            runs["baseline"].append(timed_study(baseline, model, Path(tmp, "baseline.npz")))
            runs["this"].append(timed_study(HERE, model, Path(tmp, "this.npz")))
        differences = output_differences(Path(tmp, "baseline.npz"), Path(tmp, "this.npz"))
    med = {k: float(np.median([r["wall_s"] for r in v])) for k, v in runs.items()}
    cpu = {k: float(np.median([r["cpu_s"] for r in v])) for k, v in runs.items()}
    return {"unit": "s wall, 36,000 scenes, all cores", "baseline_code": str(baseline),
            "this_median_s": round(med["this"], 3), "baseline_median_s": round(med["baseline"], 3),
            "this_runs_s": [round(r["wall_s"], 3) for r in runs["this"]],
            "baseline_runs_s": [round(r["wall_s"], 3) for r in runs["baseline"]],
            "this_rk4_steps": runs["this"][0]["rk4_steps"], "baseline_rk4_steps": runs["baseline"][0]["rk4_steps"],
            "speedup": round(med["baseline"] / med["this"], 2),
            "this_cpu_median_s": round(cpu["this"], 3), "baseline_cpu_median_s": round(cpu["baseline"], 3),
            "this_cpu_runs_s": [round(r["cpu_s"], 3) for r in runs["this"]],
            "baseline_cpu_runs_s": [round(r["cpu_s"], 3) for r in runs["baseline"]],
            "speedup_cpu": round(cpu["baseline"] / cpu["this"], 2), "outputs_this_vs_baseline": differences,
            "compared": "baseline median over this median, alternating runs in one run of this script"}


def sample_scenes(records: list, n: int, seed: int) -> list[tuple]:
    rng = np.random.default_rng(seed)
    return [(TABLE_I[rng.integers(len(TABLE_I))], records[rng.integers(len(records))],
             int(rng.choice([1, -1])), float(rng.choice(ANGLES))) for _ in range(n)]


def reference_time(model: str, scenes: list[tuple]) -> float:
    """Mean seconds per scene of the reference solver (one core)."""
    t0 = time.perf_counter()
    for body, rec, sgn, beta in scenes:
        simulate(body, sgn * rec.acc_h, rec.dt, beta=beta, model=model, solver="reference")
    return (time.perf_counter() - t0) / len(scenes)


def paper_study(model: str, records: list, results: dict) -> dict:
    study(TABLE_I[:2], records[:2], ANGLES[:2], model=model)  # compile / load the cache
    res = study(TABLE_I, records, ANGLES, model=model)
    results[model] = res
    avg = res.average_cor()
    fit = res.fit_gcor()
    per_step = res.seconds / max(int(res.steps.sum()), 1)
    durations = np.array([rec.dt * rec.acc_h.size for rec in records])
    pre = res.prescreened
    # what the pre-screened scenes would have cost integrated over their whole record at the
    # study's step, at the measured time per RK4 step
    h = np.array([0.05 / res.bodies[j].p for j in res.body])  # p·h = DEFAULT_STEP
    skipped_steps = float(np.sum(durations[res.record[pre]] / h[pre]))
    return {
        "scenes": res.scenes,
        "wall_s": round(res.seconds, 3),
        "scenes_per_s": round(res.scenes / res.seconds, 1),
        "cores": os.cpu_count(),
        "rk4_steps": int(res.steps.sum()),
        "prescreened_scenes": int(pre.sum()),
        "prescreened_fraction": round(float(pre.mean()), 4),
        "prescreen_time_saved_s_estimate": round(skipped_steps * per_step, 3),
        "prescreen_note": "integration the pre-screened scenes did not need: their record length at p·h = 0.05, "
                          "at the measured time per RK4 step",
        "undecided": int(np.count_nonzero(res.status == 2)),
        "cor_by_angle": [{"angle_deg": r["angle_deg"],
                          "cor_pct": None if r["cor"] is None else round(100 * r["cor"], 1),
                          "overturned": r["overturned"], "paper_table_ii_pct": p,
                          "eq11_paper_pct": round(100 * float(gcor(r["angle_rad"])), 1)}
                         for r, p in zip(avg, PAPER_TABLE_II, strict=True)],
        "gcor_fit": fit.as_dict(),
        "paper_gcor": {"c1": 0.048, "c2": 0.48},
    }


def pareto(model: str, bodies: list, records: list, ag: Agreement) -> list[dict]:
    """The fast study at several steps p·h against the reference on the agreement set: run time per
    scene (all cores) against error. At least one RK4 step per sample interval is always taken, so
    steps above p·dt give the same engine."""
    out = []
    for step in STEPS:
        res = study(bodies, records, AGREEMENT_ANGLES, model=model, step=step)
        same = res.direction == ag.reference_direction
        both = same & (res.direction != 0)
        rest = same & (res.direction == 0) & ~res.prescreened
        t_err = np.abs(res.t_overturn[both] - ag.reference_t_overturn[both])
        th_err = np.abs(res.theta_max[rest] - ag.reference_theta_max[rest])
        out.append({"step_p_h": step, "rk4_steps": int(res.steps.sum()),
                    "wall_s": round(res.seconds, 4), "seconds_per_scene": res.seconds / res.scenes,
                    "classification_agreement": float(same.mean()),
                    "t_overturn_err_median_s": float(np.median(t_err)) if t_err.size else None,
                    "t_overturn_err_max_s": float(np.max(t_err)) if t_err.size else None,
                    "theta_max_err_median_rad": float(np.median(th_err)) if th_err.size else None,
                    "theta_max_err_max_rad": float(np.max(th_err)) if th_err.size else None,
                    "scenes": res.scenes})
    return out


def general_vs_rocking(rocking: StudyResult, general: StudyResult) -> dict:
    """The paper found the two models' COR within 4 %: our figure, per body and angle and averaged."""
    rows = [(a["cor"], b["cor"]) for a, b in zip(rocking.cor(), general.cor(), strict=True)
            if a["cor"] is not None and b["cor"] is not None]
    avg = [(a["cor"], b["cor"]) for a, b in zip(rocking.average_cor(), general.average_cor(), strict=True)
           if a["cor"] is not None and b["cor"] is not None]
    same = float(np.mean(rocking.direction == general.direction))
    return {"max_cor_difference_pp_per_body_angle": round(100 * max(abs(a - b) for a, b in rows), 2),
            "max_cor_difference_pp_average": round(100 * max(abs(a - b) for a, b in avg), 2),
            "same_direction_fraction": same, "paper": "within 4 %", "friction": general.settings["friction"]}


ENERGY_BODIES = (TABLE_I[0], TABLE_I[-1], Body(b=0.05, h=0.05), Body(b=0.0025, h=0.05), Body(b=1.0, h=5.0))


def energy_growth(model: str) -> list[dict]:
    """Largest relative energy gain over 60 s of free rocking with e = 1 (level plate, released at
    0.1, 0.3, 0.6 and 0.9 α) over ENERGY_BODIES, per step p·h."""
    out = []
    for step in STEPS[1:5]:
        gains = [free_rocking_energy_growth(b, f * b.alpha, step=step, model=model)
                 for b in ENERGY_BODIES for f in (0.1, 0.3, 0.6, 0.9)]
        out.append({"step_p_h": step, "max_relative_gain": max(gains), "cases": len(gains)})
    return out


def stressed(records: list, quick: bool) -> dict:
    ag = compare_stressed(stressed_scenes(list(TABLE_I), records, 100 if quick else 600, seed=26))
    return {**asdict(ag), "reference_seconds": round(ag.reference_seconds, 1),
            "set": "Table I x FEMA P695, mu U(0.1, 0.6), either sign, beta U(0, 10) deg, vertical (partner "
                   "component, peak U(0.3, 1.5) g) in half; seed 26"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller agreement set and samples")
    ap.add_argument("--models", default="rocking,general")
    ap.add_argument("--baseline", type=Path, help="a checkout to time the paper-scale study against")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each side with --baseline")
    ap.add_argument("--only-timing", action="store_true", help="with --baseline: only the timed comparison")
    args = ap.parse_args()
    records = load_records("fema")
    report: dict = {"benchmark": "analysis engines", "machine_cores": os.cpu_count(), "records": len(records),
                    "models": {}}
    studies: dict = {}
    for model in args.models.split(","):
        if args.baseline is not None:
            report["models"][model] = {"paper_scale_study_vs_baseline": versus_baseline(model, args.baseline.resolve(),
                                                                                        args.repeats)}
            if args.only_timing:
                continue
        entry: dict = {**report["models"].get(model, {}), "paper_scale_study": paper_study(model, records, studies)}
        sample = sample_scenes(records, 20 if args.quick else 60, seed=1)
        ref_s = reference_time(model, sample)
        fast_s = entry["paper_scale_study"]["wall_s"] / entry["paper_scale_study"]["scenes"]
        entry["reference"] = {"seconds_per_scene": ref_s, "sample_scenes": len(sample), "method": "DOP853 rtol 1e-11"}
        entry["speedup_per_scene"] = {"figure": round(ref_s / fast_s, 1), "unit": "x",
                                      "compared": "reference s/scene (1 core) over fast study wall s/scene (all cores)",
                                      "per_core": round(ref_s / (fast_s * (os.cpu_count() or 1)), 1)}
        bodies, recs = (list(TABLE_I[::3]), records[::5]) if args.quick else (list(TABLE_I), records)
        ag = compare_with_reference(bodies, recs, AGREEMENT_ANGLES, model=model)
        entry["agreement"] = {
            "scenes": ag.scenes, "same_direction_fraction": ag.fraction_same,
            "max_cor_difference_pp": ag.max_cor_difference_pp, "t_overturn_max_error_s": ag.t_overturn_max_error,
            "differing_scenes": [asdict(d) for d in ag.differences],
            "unexplained_differences": len(ag.unexplained), "reference_wall_s": round(ag.reference_seconds, 1),
            "targets": {"same_direction_fraction": ">= 0.995", "max_cor_difference_pp": "<= 0.5"}}
        entry["pareto_step_vs_error"] = pareto(model, bodies, recs, ag)
        entry["free_rocking_e1_energy_gain_60s"] = energy_growth(model)
        if model == "general":
            entry["stressed_agreement"] = stressed(records, args.quick)
        report["models"][model] = entry
        print(json.dumps({"progress": model, "done": True}), flush=True, file=sys.stderr)
    if {"rocking", "general"} <= studies.keys():
        report["general_vs_rocking"] = general_vs_rocking(studies["rocking"], studies["general"])
    print(json.dumps(report, indent=1, default=lambda o: None if isinstance(o, float) and math.isnan(o) else o))


if __name__ == "__main__":
    main()
