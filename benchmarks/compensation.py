"""Benchmark: drive compensation, the diagonal law beside the MIMO one in the same run, on the servo-hydraulic table
with the seven Table V bodies, the ten strongest FEMA P695 components, at 0° and 5°.

For each angle the table is identified once (the band-limited random drive on all three axes at once) and each
record's drive prepared with the headroom (10 % by default) is iterated with each law through the same loop
(``rig.compensation.iteration``: level ramp −12, −6, 0 dB, every play checked against the plate's predicted response,
roll-back), three full-level plays at most. Per case and law: the uncompensated error (the first play, the drive as
prepared at −12 dB, and the predicted peak / limit the drive as prepared would have had at full level — what the
first play did before every play was checked), every play's level and errors per axis and along the fall line, TRAC
and 5 % response-spectrum error, the full-level plays needed to reach ≤ 5 % fall-line RMS error, the largest
achieved acceleration / its Table IV limit over every play (≤ 1 for a play inside the limits) and the time per play;
offline also each play's predicted peak acceleration / its limit (the response the play was checked on,
``predicted_peak_to_limit``) and, in the summary, the largest ratio of achieved to predicted peak.

**How the table is played.** By default offline: ``sim_table.offline.play_offline`` runs the emulator's own
physics — the legs as ``rig emulate --dynamics servo`` (the rigid plate with the bodies' mass on the six legs along
their axes: its surge and lateral modes near 4.2 Hz), the plate track, the accelerometers with their noise — on
the drive's 1 kHz samples, without a transport or a clock: virtual time, every play as fast as the machine computes
it. With ``--emulator``
each case runs instead through ``rig iterate``'s own path (``rig.compensation.session``) on an emulator process at
``--speed max`` (virtual time, MAVLink on loopback, the seven bodies in MuJoCo); under heavy load the stream's
watchdog can stop a play, which the case then records.

Targets (issue 23): ≤ 5 % in ≤ 3 full-level plays for ≥ 9 of 10 records with 10 % headroom, ≤ 2 % where the limits
leave room, no play beyond a limit. Each case also reports its accelerometer's noise floor (``noise_floor_pct``, at
full level, pooled over its plays: ``rig.compensation.iteration.pooled_floor``) — an error no play can go below — and
the summary counts the ≤ 2 % cases among those whose floor is below 2 %.

Usage: ``python benchmarks/compensation.py [--quick] [--records N] [--angles 0,5] [--iterations N]
[--headroom 0.1] [--emulator]``; prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.body import TABLE_V
from analysis.table.dynamics import PlateLoad, plate_modes
from analysis.table.model import TableModel
from protocols.signing_key import write_signing_key
from rig.compensation.identify import frequency_response, identification_drive
from rig.compensation.iteration import Compensation, compensate, pooled_floor
from rig.compensation.laws import DiagonalLaw, MimoLaw
from rig.compensation.mimo import estimate
from rig.compensation.safety import LEVELS_DB, PredictedLimitError, predicted_peak_ratio
from rig.compensation.signals import base_accelerations
from rig.drive import Drive, prepare_drive
from rig.records import load_record
from rig.sequence.records import expand_records_from
from sim_table.offline import play_offline

TARGET_PCT = 5.0
FINE_PCT = 2.0
TARGET_PLAYS = 3
"""Full-level plays the issue's ≤ 5 % target allows (``--iterations`` may allow more, to see where ≤ 2 % is
reached)."""
LAWS = ("diagonal", "mimo")


def _plays_to(full: list[Any], pct: float) -> int | None:
    """The number of full-level plays it took to reach ``pct`` fall-line RMS error, or None."""
    return next((k + 1 for k, it in enumerate(full) if it.rms_error_pct <= pct), None)


def _outcome(result: Compensation, predicted_full: float) -> dict[str, Any]:
    """One law's JSON on one case."""
    plays = [it.to_json() for it in result.iterations]
    full = [it for it in result.iterations if it.level_db == 0.0]
    return {
        "uncompensated": {"rms_error_pct": result.iterations[0].rms_error_pct,
                          "level_db": result.iterations[0].level_db,
                          "predicted_peak_to_limit_at_full_level": predicted_full},
        "plays": [{key: p[key] for key in ("level_db", "rms_error_pct", "peak_error_pct", "axes", "psa_error_max_pct",
                                           "psa_error_mean_pct", "peak_to_limit", "predicted_peak_to_limit",
                                           "gain", "seconds") if key in p}
                  | {"trac": p["fall_line"]["trac"], "noise_floor_pct": p["fall_line"]["noise_floor_pct"]}
                  for p in plays],
        "rms_error_pct_by_play": [round(it.rms_error_pct, 3) for it in result.iterations],
        "full_level_plays_to_5_pct": _plays_to(full, TARGET_PCT),
        "full_level_plays_to_2_pct": _plays_to(full, FINE_PCT),
        "best_full_level_rms_error_pct": min((it.rms_error_pct for it in full), default=None),
        "noise_floor_pct": pooled_floor(result.iterations),
        "largest_peak_to_limit": max(it.measures.peak_to_limit for it in result.iterations),
        "seconds_per_play": statistics.mean(it.seconds for it in result.iterations),
        "stopped": result.stopped,
    }


def _offline(args: argparse.Namespace, table: TableModel, payload: float, specs: list[str]
             ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    cases, identification = [], {}
    levels = tuple(float(x) for x in args.levels.split(","))
    for angle_deg in args.angles:
        beta = math.radians(angle_deg)
        started = time.perf_counter()
        ident = identification_drive(table, beta, duration=args.identify_seconds, seed=3)
        measured = base_accelerations(play_offline(table, ident.poses, payload=payload, seed=1), beta)
        commanded = ident.accelerations[:, :3]
        diagonal = frequency_response(commanded, measured, table.controller_rate)
        matrix = estimate(commanded, measured, table.controller_rate)
        worst, at = matrix.peak_condition()
        identification[f"{angle_deg:g}"] = {
            "seconds": time.perf_counter() - started, "drive_seconds": ident.duration,
            "largest_condition_number": worst, "at_hz": at,
            "surge_peak_gain": float(np.abs(matrix.h[:, 0, 0]).max()),
            "surge_peak_hz": float(matrix.f[int(np.abs(matrix.h[:, 0, 0]).argmax())])}
        for k, spec in enumerate(specs):
            drive = prepare_drive(load_record(spec), angle=beta, table=table, ramps=False, headroom=args.headroom)
            case: dict[str, Any] = {"record": spec, "angle_deg": angle_deg, "drive_seconds": drive.duration,
                                    "scale_factor": drive.scale_factor}
            predicted = predicted_peak_ratio(drive, matrix)
            for name in LAWS:
                law = DiagonalLaw(diagonal) if name == "diagonal" else MimoLaw(matrix)

                def play(d: Drive, i: int, k: int = k) -> np.ndarray:
                    return play_offline(table, d.poses, payload=payload, seed=100 * k + i)

                try:
                    result = compensate(drive, law, play, iterations=args.iterations, levels_db=levels)
                except PredictedLimitError as exc:
                    case[name] = {"refused": str(exc)}
                    continue
                case[name] = _outcome(result, predicted)
            cases.append(case)
            print(json.dumps({"progress": spec, "angle_deg": angle_deg,
                              **{n: case[n].get("rms_error_pct_by_play") for n in LAWS}}), flush=True,
                  file=sys.stderr)
    return cases, identification


def _emulator(args: argparse.Namespace, table: TableModel, specs: list[str], scratch: Path) -> list[dict[str, Any]]:
    """Every case through ``rig iterate``'s path on an emulator process in virtual time (``--speed max``)."""
    from rig.compensation.session import iterate_on_table
    from rig.emulator import EmulatorProcess

    key = scratch / "bench.key"
    write_signing_key(key)
    flags, bodies = ["--dynamics", "servo", "--speed", "max"], []
    gap = 0.05
    edge = -(sum(body.depth for body in TABLE_V) + gap * (len(TABLE_V) - 1)) / 2
    for k, body in enumerate(TABLE_V):  # side by side across the plate (along y), each centred on the fall line
        y = edge + body.depth / 2
        edge += body.depth + gap
        flags += ["--body", f"{body.b!r}x{body.h!r}@0,{y!r};depth={body.depth!r};mass={body.mass!r}"]
        bodies.append({"body_id": k + 1, "name": body.name, "b": body.b, "h": body.h, "depth": body.depth,
                       "mass": body.mass, "x": 0.0, "y": y})
    levels = tuple(float(x) for x in args.levels.split(","))
    cases, count = [], 0
    for angle_deg in args.angles:
        for spec in specs:
            drive = prepare_drive(load_record(spec), angle=math.radians(angle_deg), table=table, ramps=False,
                                  headroom=args.headroom)
            case: dict[str, Any] = {"record": spec, "angle_deg": angle_deg, "drive_seconds": drive.duration}
            for name in LAWS:
                count += 1
                emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", *flags, key_file=key)
                try:
                    outcome = iterate_on_table(drive, emulator.url, {"key_file": str(key)}, scratch / f"s{count}.h5",
                                               scratch / f"s{count}.drive.h5", sequence={"name": "benchmark"},
                                               software_version="benchmark", bodies=bodies, law=name,
                                               iterations=args.iterations, levels_db=levels,
                                               identify_seconds=args.identify_seconds)
                    case[name] = _outcome(outcome.result, math.nan)
                except Exception as exc:  # one case's failure is a result; the other cases still run
                    case[name] = {"failed": f"{type(exc).__name__}: {exc}"}
                finally:
                    counters = emulator.stop()
                if "failed" in case[name]:  # the emulator's view of the failure: did it stall, or the host?
                    case[name]["emulator"] = {"timing": counters["timing"], "faults": counters["faults"]}
            cases.append(case)
    return cases


def _summary(cases: list[dict[str, Any]], iterations: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in LAWS:
        done = [c[name] for c in cases if "plays" in c.get(name, {})]
        best = [d["best_full_level_rms_error_pct"] for d in done if d["best_full_level_rms_error_pct"] is not None]
        out[name] = {
            "cases": len(cases), "played": len(done),
            "refused_or_failed": len(cases) - len(done),
            f"reached_{TARGET_PCT:g}_pct_within_{TARGET_PLAYS}_full_level_plays": sum(
                1 for d in done if (d["full_level_plays_to_5_pct"] or TARGET_PLAYS + 1) <= TARGET_PLAYS),
            f"reached_{FINE_PCT:g}_pct_within_{TARGET_PLAYS}_full_level_plays": sum(
                1 for d in done if (d["full_level_plays_to_2_pct"] or TARGET_PLAYS + 1) <= TARGET_PLAYS),
            f"reached_{FINE_PCT:g}_pct_within_{iterations}_full_level_plays": sum(1 for b in best if b <= FINE_PCT),
            f"noise_floor_below_{FINE_PCT:g}_pct": sum(1 for d in done if (d["noise_floor_pct"] or 0.0) < FINE_PCT),
            f"reached_{FINE_PCT:g}_pct_where_the_noise_floor_is_below_it": sum(
                1 for d in done if (d["noise_floor_pct"] or 0.0) < FINE_PCT
                and (d["best_full_level_rms_error_pct"] or math.inf) <= FINE_PCT),
            "full_level_plays_to_5_pct": [d["full_level_plays_to_5_pct"] for d in done],
            "full_level_plays_to_2_pct": [d["full_level_plays_to_2_pct"] for d in done],
            "best_full_level_rms_error_pct": {"median": statistics.median(best) if best else None,
                                              "max": max(best) if best else None},
            "uncompensated_rms_error_pct_median": statistics.median(d["uncompensated"]["rms_error_pct"]
                                                                    for d in done) if done else None,
            "largest_peak_to_limit_any_play": max((d["largest_peak_to_limit"] for d in done), default=None),
            "seconds_per_play_mean": statistics.mean(d["seconds_per_play"] for d in done) if done else None,
            "achieved_over_predicted_peak_max": max((p["peak_to_limit"] / p["predicted_peak_to_limit"] for d in done
                                                     for p in d["plays"] if p.get("predicted_peak_to_limit")),
                                                    default=None),
        }
    predicted = [c["mimo"]["uncompensated"]["predicted_peak_to_limit_at_full_level"] for c in cases
                 if "plays" in c.get("mimo", {})]
    out["drives_as_prepared_predicted_beyond_a_limit_at_full_level"] = sum(1 for p in predicted if p > 1.0)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="3 records, 5° only, 30 s identification")
    p.add_argument("--records", type=int, default=10, help="the N strongest FEMA components by PGA")
    p.add_argument("--angles", type=lambda s: [float(x) for x in s.split(",")], default=[0.0, 5.0])
    p.add_argument("--iterations", type=int, default=3, help="full-level plays at most")
    p.add_argument("--levels", default=",".join(f"{x:g}" for x in LEVELS_DB), help="the ramp's levels [dB]")
    p.add_argument("--headroom", type=float, default=0.1, help="share of every limit left by the scale factor")
    p.add_argument("--identify-seconds", type=float, default=60.0)
    p.add_argument("--emulator", action="store_true", help="through the emulator process at --speed max")
    args = p.parse_args()
    if args.quick:
        args.records, args.angles, args.identify_seconds = 3, [5.0], 30.0
    table = TableModel()
    payload = sum(body.mass for body in TABLE_V)
    specs = expand_records_from("fema", args.records)
    started = time.perf_counter()
    identification: dict[str, Any] = {}
    if args.emulator:
        with tempfile.TemporaryDirectory(prefix="bench-compensation-") as scratch:
            cases = _emulator(args, table, specs, Path(scratch))
        mode = ("emulator process (rig.compensation.session over MAVLink on loopback, --dynamics servo, --speed max: "
                "virtual time, the seven Table V bodies in MuJoCo); identification per case and law")
    else:
        cases, identification = _offline(args, table, payload, specs)
        mode = ("offline: sim_table.offline.play_offline (the emulator's servo legs with the bodies' mass, plate "
                "track, accelerometers with noise; no transport, virtual time); one identification per angle shared "
                "by both laws")
    print(json.dumps({
        "benchmark": "drive compensation: diagonal and MIMO laws, servo-hydraulic table, seven Table V bodies",
        "mode": mode,
        "machine_note": "2 shared cores under other helpers' load: times are indicative",
        "table": {"plate_modes_hz_with_bodies": plate_modes(table, loads=(PlateLoad(payload, (0.0, 0.0, 0.0)),))
                  .frequencies.round(2).tolist(), "payload_kg": payload,
                  "plant": "--dynamics servo: the rigid plate on the six legs along their axes (coupled)"},
        "records": specs, "angles_deg": args.angles, "headroom": args.headroom, "levels_db": args.levels,
        "full_level_plays_max": args.iterations, "identification": identification,
        "summary": _summary(cases, args.iterations),
        "seconds_total": time.perf_counter() - started,
        "cases": cases,
    }, indent=1, allow_nan=True))


if __name__ == "__main__":
    main()
