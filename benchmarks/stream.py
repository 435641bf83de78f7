"""Benchmark: stream a prepared FEMA drive through a table transport to the emulator and measure the link and the
emulator, all in one run (loopback, real time by default). Prints one JSON object, each figure beside what it is
compared with: ``send_lateness_ms``, ``host_to_controller_ms``, ``controller_to_host_ms`` [ms], ``accelerometer``,
``emulator`` (with ``profile_cpu_us_per_tick`` [µs]), ``tracking``, ``send_timing_ms``, ``end_to_end_latency_ms``
[ms], ``messages_lost`` and ``real_time_factor`` (with ``emulator_cpu`` and ``at_1x``). What each one measures and
against what: docs/transports.md §Measuring a link.

Transports: ``mavlink`` and ``zenoh`` run the emulator as a separate process; ``canopen`` runs it in a thread of
this process on python-can's ``virtual`` bus (the only way that transport works on one host), at 500 Hz SYNC.
``--duration S`` makes the drive at least S s long: the prepared drive repeated while whole copies fit, then held
at rest (its first and last pose, both at rest) up to S s, so send timing is measured over S s at 1 kHz.
``--bodies table5`` puts the seven bodies of the paper's Table V on the plate (b × h, depth 2·b: the emulator's
``--body`` default), in a row along y with :data:`BODY_GAP` between them.

Usage: ``python benchmarks/stream.py [--transport mavlink|zenoh|canopen] [--record fema:NORTHR/MUL009] [--angle 5]
[--lead 1] [--speed 1|max] [--no-1x] [--duration S] [--bodies default|table5|none] [--no-bodies]
[--dynamics lag|servo]`` (the emulator's legs, docs/table-dynamics.md).
"""

from __future__ import annotations

import argparse
import json
import math
import secrets
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from analysis.body import TABLE_V
from drivers.controller import DEFAULT_LEAD, StreamAbortedError, open_table
from protocols.signing_key import write_signing_key
from rig.drive import prepare_drive
from rig.emulator import EmulatorProcess, parse_speed, speed_flags
from rig.records import load_record
from sim_table.options import DYNAMICS
from sim_table.process import Emulator, EmulatorConfig, parse_body

BODIES = ("0.05x0.50@0.4,0", "0.15x0.45@-0.4,0")
TAU = 0.005  # the emulator's leg lag [s]
LISTEN = {"mavlink": "mavlink://127.0.0.1:0", "zenoh": "zenoh://127.0.0.1:0/bench", "canopen": "canopen://{}?interface=virtual"}
"""Where the emulator listens, per transport (port 0: a free one; CANopen: a fresh virtual channel)."""
BODY_GAP = 0.05
"""Free space between neighbouring Table V bodies along y [m]."""
RTF_TARGET = 2.0
"""The emulator's real-time factor issue 4 asks for with the Table V bodies on the plate."""
VIRTUAL_RTF_TARGET = 15.0
"""A stream's real-time factor in virtual time (``--speed max``) issue 41 asks for with the Table V bodies (issue 11
asked for 10×)."""
MAX_LAG = 0.2
"""Largest command → achieved lag searched [s]."""


def table5_bodies() -> tuple[str, ...]:
    """The seven Table V bodies as ``--body BxH@X,Y``: at x = 0, side by side along y (depth 2·b), gaps of
    :data:`BODY_GAP`, the row centred on the plate."""
    depths = [2.0 * body.b for body in TABLE_V]
    y = -0.5 * (sum(depths) + BODY_GAP * (len(depths) - 1))
    placed = []
    for body, depth in zip(TABLE_V, depths, strict=True):
        placed.append(f"{body.b:g}x{body.h:g}@0,{y + 0.5 * depth:.4f}")
        y += depth + BODY_GAP
    return tuple(placed)


def tick_rtf(tick_us: float | None, rate: float) -> float | None:
    """Controller time per second of compute at ``tick_us`` [µs] a tick at the controller's ``rate`` [Hz]."""
    return 1e6 / rate / tick_us if tick_us else None


def lengthen(t: np.ndarray, poses: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """The drive repeated while whole copies fit in ``duration`` [s], then held at its last pose up to it."""
    spacing = float(t[1] - t[0])
    total = round(duration / spacing) + 1
    if total <= len(t):
        return t, poses
    copies = max(1, (total - 1) // (len(t) - 1))
    parts = [poses] + [poses[1:]] * (copies - 1)
    looped = np.concatenate(parts)
    held = np.concatenate([looped, np.repeat(looped[-1:], total - len(looped), axis=0)])
    return t[0] + np.arange(total) * spacing, held


def best_lag(t_ns: np.ndarray, achieved: np.ndarray, t_start_ns: int, spacing_ns: int,
             commanded: np.ndarray) -> dict[str, float]:
    """The lag [ms] that minimises the squared error between achieved(t) and commanded(t − lag), with the rms
    residue there and at zero lag."""
    if len(t_ns) < 10:
        return {}
    lags = np.arange(0.0, MAX_LAG * 1e9, 1e5)  # 0.1 ms steps
    grid = np.arange(len(commanded))
    errors = np.array([np.mean((achieved - np.interp((t_ns - lag - t_start_ns) / spacing_ns, grid, commanded)) ** 2)
                       for lag in lags])
    best = int(errors.argmin())
    return {"best_lag": float(lags[best]) * 1e-6, "rms_residual_mm": math.sqrt(errors[best]) * 1e3,
            "rms_at_zero_lag_mm": math.sqrt(errors[0]) * 1e3, "search_max": MAX_LAG * 1e3, "statuses": len(t_ns),
            "method": "least squares of achieved surge vs commanded surge delayed by the lag (status times, "
                      "controller clock)"}


class _Thread:
    """The emulator in a thread of this process (CANopen on the virtual bus)."""

    def __init__(self, url: str, bodies: tuple[str, ...], speed: float, dynamics: str) -> None:
        self.emulator = Emulator(EmulatorConfig(listen=url, key=secrets.token_bytes(32), speed=speed,
                                                specimens=tuple(parse_body(b) for b in bodies), dynamics=dynamics))
        self.stop_event = threading.Event()
        self.thread = threading.Thread(target=self.emulator.run, args=(self.stop_event,), name="emulator",
                                       daemon=True)
        self.thread.start()
        self.url = self.emulator.url

    def stop(self, timeout: float) -> dict[str, Any]:
        self.stop_event.set()
        self.thread.join(timeout=timeout)
        try:
            return self.emulator.counters()
        finally:
            self.emulator.close()


@contextmanager
def _started(transport: str, bodies: tuple[str, ...], speed: float, key_file: Path, dynamics: str) -> Iterator[Any]:
    if transport == "canopen":
        yield _Thread(LISTEN[transport].format(f"bench-{uuid.uuid4().hex}"), bodies, speed, dynamics)
    else:
        flags = speed_flags(speed) + [arg for body in bodies for arg in ("--body", body)] + ["--dynamics", dynamics]
        yield EmulatorProcess.start(LISTEN[transport], *flags, key_file=key_file)


def _percentiles(values: np.ndarray, scale: float) -> dict[str, float]:
    if len(values) == 0:
        return {}
    p50, p99 = np.percentile(values, [50, 99])
    return {"min": float(values.min()) * scale, "p50": p50 * scale, "p99": p99 * scale,
            "max": float(values.max()) * scale}


def run(transport: str, record: str, angle_deg: float, lead: float, speed: float, bodies: bool | tuple[str, ...],
        duration: float | None = None, dynamics: str = "lag") -> dict[str, Any]:
    placed = (BODIES if bodies else ()) if isinstance(bodies, bool) else tuple(bodies)
    drive = prepare_drive(load_record(record), angle=math.radians(angle_deg))
    t, poses = lengthen(drive.t, drive.poses, duration) if duration else (drive.t, drive.poses)
    canopen = transport == "canopen"
    with tempfile.TemporaryDirectory(prefix="stream-bench-") as scratch:
        key_file = Path(scratch) / "rig.key"
        write_signing_key(key_file)
        with _started(transport, placed, speed, key_file, dynamics) as emulator:
            try:
                options = {} if canopen else {"key_file": str(key_file)}
                table: Any = open_table(emulator.url, **options)  # every driver has link_stats()
                with table:
                    statuses, accel, detections = table.statuses(), table.accelerations(), table.detections()
                    table.arm()
                    started = time.monotonic()
                    try:
                        report, aborted = table.stream(t, poses, lead=lead), None
                    except StreamAbortedError as exc:  # still report how far it got and why
                        report, aborted = exc.report, str(exc)
                    wall = time.monotonic() - started
                    time.sleep(0.6)  # the last overturn event's repetitions, the last accelerometer batch
                    stats = table.link_stats()
                    received = statuses.drain()
                    # CANopen: controller time is this host's monotonic clock
                    to_host = (lambda ns: ns) if canopen else table.clock.to_host
                    status_latency = np.array([s.host_ns - to_host(s.t_ns) for s in received])
                    round_trips = np.zeros(0) if canopen else np.array(table.clock.round_trips, dtype=np.float64)
            finally:
                counters = emulator.stop(timeout=30)

    virtual = math.isinf(speed)
    if virtual:  # controller time per real time, as achieved: what the per-real-time figures are scaled by
        speed = report.duration / wall
    spacing = round(1e9 / drive.rate)
    during = [s for s in received if report.t_start_ns <= s.t_ns <= report.t_end_ns]
    k = (np.array([s.t_ns for s in during]) - report.t_start_ns) / spacing
    achieved_surge = np.array([s.pose[0] for s in during])
    commanded = np.interp(k, np.arange(len(t)), poses[:, 0])
    surge_error = np.abs(achieved_surge - commanded)
    batches = accel.drain()
    times = np.concatenate([b.times_ns() for b in batches]) if batches else np.zeros(0, dtype=np.int64)
    inside = int(((times >= report.t_start_ns) & (times <= report.t_end_ns)).sum())
    lateness = report.send_lateness_ns.astype(np.float64)
    chunks_accepted = counters.get("chunks_accepted", 0)
    margin_mean = counters.get("chunk_margin_total_ns", 0) / max(chunks_accepted, 1)
    timing = counters["timing"]
    found = detections.drain()
    sample_rate = (stats["rate_hz"] if canopen else drive.rate) * speed
    period_ms = (1e3 / stats["rate_hz"] if canopen else report.samples / max(report.chunks, 1) * spacing * 1e-6) / speed
    velocity = np.gradient(poses[:, 0], spacing * 1e-9)
    rtf = timing["real_time_factor"]
    lost = stats.get("accel_batches_lost", stats.get("accel_samples_lost", 0))
    send_unit = (f"SYNC cycle ({stats['rate_hz']:g} Hz: the master interpolates the 1 kHz drive and sends the six "
                 "drives their targets each cycle)") if canopen else "setpoint chunk"
    return {
        "drive": {"transport": transport, "record": record, "angle_deg": angle_deg, "duration_s": report.duration,
                  "prepared_drive_s": drive.duration, "sample_rate_hz": drive.rate,
                  "speed": "max (virtual time)" if virtual else speed,
                  "bodies": list(placed), "wall_s": wall, "aborted": aborted,
                  "emulator": "thread of this process, python-can virtual bus" if canopen else "separate process"},
        "send_lateness_ms": {**_percentiles(lateness, 1e-6),
                             "chunk_period_ms": period_ms,
                             "lead_ms": lead * 1e3 / speed, "chunks": report.chunks},
        "send_timing_ms": {"per": send_unit, **({"p50_jitter": float(np.percentile(lateness, 50)) * 1e-6,
                                                 "p99_jitter": float(np.percentile(lateness, 99)) * 1e-6,
                                                 "max_jitter": float(lateness.max()) * 1e-6} if len(lateness) else {}),
                           "period": period_ms,
                           "sends": len(lateness), "over_s": report.duration,
                           **({"late_cycles": stats["late_cycles"]} if canopen else {})},
        "end_to_end_latency_ms": best_lag(np.array([s.t_ns for s in during], dtype=np.float64), achieved_surge,
                                          report.t_start_ns, spacing, poses[:, 0]),
        "host_to_controller_ms": {} if canopen else {
            "mean": (lead * 1e9 - margin_mean) / speed * 1e-6 - (lateness.mean() if len(lateness) else 0) * 1e-6,
            "worst_bound": (lead * 1e9 - (counters.get("chunk_margin_min_ns") or 0)) / speed * 1e-6,
            "timesync_half_round_trip": _percentiles(round_trips / 2, 1e-6),
        },
        "controller_to_host_ms": {**_percentiles(status_latency, 1e-6), "statuses": len(received)},
        "accelerometer": {
            "samples_per_s": len(times) / (wall + 0.6) if batches else 0.0,
            "rate_hz": sample_rate,
            ("samples_lost" if canopen else "batches_lost"): lost,
            "samples_in_stream": inside,
            "expected_in_stream": round(report.duration * (stats["rate_hz"] if canopen else drive.rate)) + 1,
        },
        "messages_lost": {("accel_samples_lost" if canopen else "accel_batches_lost"): lost,
                          "chunks_missing": counters.get("chunks_missing"),
                          "samples_late": counters.get("samples_late"),
                          "emulator_underruns": counters.get("underruns")},
        "emulator": {key: timing[key] for key in ("tick_time_mean_us", "tick_time_p99_us", "tick_cpu_mean_us",
                                                    "tick_budget_us",
                                                    "real_time_factor", "batch_size_mean", "batch_size_max",
                                                    "lag_max_ms", "profile_cpu_us_per_tick")},
        "real_time_factor": ({"measured": speed, "what": "stream controller time / wall time (virtual time)",
                              "target": VIRTUAL_RTF_TARGET, "meets_target": speed >= VIRTUAL_RTF_TARGET,
                              "emulator_compute": rtf,
                              "emulator_cpu": tick_rtf(timing["tick_cpu_mean_us"], drive.rate),
                              "bodies": len(placed)} if virtual else
                             {"measured": rtf, "target": RTF_TARGET,
                              "meets_target": rtf is not None and rtf >= RTF_TARGET, "bodies": len(placed)}),
        "tracking": {
            "surge_error_max_mm": float(surge_error.max()) * 1e3 if len(surge_error) else None,
            "v_max_tau_mm": float(np.abs(velocity).max()) * TAU * 1e3,
            "underruns": report.underruns,
            "overturns": [{"body_id": d.body_id, "direction": d.direction, "t_s": d.t_ns * 1e-9} for d in found],
            "duplicate_overturn_copies_dropped": stats["duplicate_detections"],
        },
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--transport", choices=sorted(LISTEN), default="mavlink")
    p.add_argument("--record", default="fema:NORTHR/MUL009")
    p.add_argument("--angle", type=float, default=5.0, help="static tilt [deg]")
    p.add_argument("--lead", type=float,
                   help="setpoint lead [s, controller time] (default: the rig TOML's [controller] lead_s, 1 s, as a "
                        "lab plays)")
    p.add_argument("--speed", type=parse_speed, default=1.0,
                   help="emulator speed (controller time per real time), or max: virtual time")
    p.add_argument("--no-1x", action="store_true", help="with --speed max: no 1x run beside it")
    p.add_argument("--duration", type=float, help="stream at least this long [s] (the drive looped, then held)")
    p.add_argument("--bodies", choices=("default", "table5", "none"), default="default",
                   help="specimens: two default bodies, the seven of Table V, or none")
    p.add_argument("--no-bodies", action="store_true", help="no specimens on the plate (= --bodies none)")
    p.add_argument("--dynamics", choices=DYNAMICS, default="lag", help="the emulator's legs (docs/table-dynamics.md)")
    args = p.parse_args()
    bodies = () if args.no_bodies or args.bodies == "none" else table5_bodies() if args.bodies == "table5" else BODIES
    lead = args.lead if args.lead is not None else DEFAULT_LEAD
    result = run(args.transport, args.record, args.angle, lead, args.speed, bodies, args.duration, args.dynamics)
    result["dynamics"] = args.dynamics
    if math.isinf(args.speed) and not args.no_1x:
        at_1x = run(args.transport, args.record, args.angle, lead, 1.0, bodies, args.duration, args.dynamics)
        result["at_1x"] = {key: at_1x[key] for key in ("drive", "real_time_factor", "messages_lost", "emulator",
                                                         "send_lateness_ms", "tracking")}
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
