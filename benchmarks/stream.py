"""Benchmark: stream a prepared FEMA drive through a table transport (MAVLink over UDP, or zenoh) to the emulator
and measure the link and the emulator, all in one run (loopback, the emulator a separate process, real time by
default).

Prints one JSON object, each figure beside what it is compared with:

* ``send_lateness_ms``: setpoint chunk send time − its deadline on the host (p50, p99, max), against the chunk
  period (8 ms at 1 kHz) and the lead (what lateness may use up before an underrun);
* ``host_to_controller_ms``: one-way latency of a chunk, from the controller's arrival stamps and the host's send
  times on the TIMESYNC-aligned clocks: mean (lead − mean arrival margin − mean send lateness) and worst bound
  (lead − smallest margin, which includes the send lateness); and half the TIMESYNC round trip (min, p50, p99);
* ``controller_to_host_ms``: status arrival on the host − its controller time stamp (p50, p99): the emulator's
  batching (a wake every 2 ms) plus the link;
* ``accelerometer``: samples per second received per sensor against the 1 kHz sampling rate, batches lost, samples
  inside the stream against duration × rate;
* ``emulator``: tick compute time (wall: mean, p99; and the tick thread's CPU time) against the tick budget
  (1 ms / speed), the real-time factor (controller time simulated per wall second of compute), batch sizes and the
  largest lag behind real time (how late the oldest tick of a batch ran);
* ``tracking``: largest |achieved − commanded| surge against v_max · τ, underruns, overturns (and the retransmitted
  copies the driver dropped).

Usage: ``python benchmarks/stream.py [--transport mavlink|zenoh] [--record fema:NORTHR/MUL009] [--angle 5]
[--lead 0.05] [--speed 1] [--no-bodies]``.
"""

from __future__ import annotations

import argparse
import json
import math
import secrets
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from drivers.controller import open_table
from rig.drive import prepare_drive
from rig.emulator import EmulatorProcess
from rig.records import load_record

BODIES = ("0.05x0.50@0.4,0", "0.15x0.45@-0.4,0")
TAU = 0.005  # the emulator's leg lag [s]
LISTEN = {"mavlink": "mavlink://127.0.0.1:0", "zenoh": "zenoh://127.0.0.1:0/bench"}
"""Where the emulator listens, per transport (port 0: a free one)."""


def _percentiles(values: np.ndarray, scale: float) -> dict[str, float]:
    if len(values) == 0:
        return {}
    p50, p99 = np.percentile(values, [50, 99])
    return {"min": float(values.min()) * scale, "p50": p50 * scale, "p99": p99 * scale,
            "max": float(values.max()) * scale}


def run(transport: str, record: str, angle_deg: float, lead: float, speed: float, bodies: bool) -> dict[str, Any]:
    drive = prepare_drive(load_record(record), angle=math.radians(angle_deg))
    with tempfile.TemporaryDirectory(prefix="stream-bench-") as scratch:
        key_file = Path(scratch) / "rig.key"
        key_file.write_text(secrets.token_hex(32))
        flags = ["--speed", str(speed)] + [arg for body in (BODIES if bodies else ()) for arg in ("--body", body)]
        emulator = EmulatorProcess.start(LISTEN[transport], *flags, key_file=key_file)
        try:
            table: Any = open_table(emulator.url, key_file=str(key_file))  # both drivers have clock, link_stats()
            with table:
                statuses, accel, detections = table.statuses(), table.accelerations(), table.detections()
                table.arm()
                started = time.monotonic()
                report = table.stream(drive.t, drive.poses, lead=lead)
                wall = time.monotonic() - started
                time.sleep(0.5)  # the last overturn event's repetitions
                stats = table.link_stats()
                received = statuses.drain()
                status_latency = np.array([s.host_ns - table.clock.to_host(s.t_ns) for s in received])
                round_trips = np.array(table.clock.round_trips, dtype=np.float64)
        finally:
            counters = emulator.stop(timeout=30)

    spacing = round(1e9 / drive.rate)
    during = [s for s in received if report.t_start_ns <= s.t_ns <= report.t_end_ns]
    k = (np.array([s.t_ns for s in during]) - report.t_start_ns) / spacing
    commanded = np.interp(k, np.arange(len(drive.t)), drive.poses[:, 0])
    surge_error = np.abs(np.array([s.pose[0] for s in during]) - commanded)
    batches = accel.drain()
    times = np.concatenate([b.times_ns() for b in batches]) if batches else np.zeros(0, dtype=np.int64)
    inside = int(((times >= report.t_start_ns) & (times <= report.t_end_ns)).sum())
    lateness = report.send_lateness_ns.astype(np.float64)
    margin_mean = counters["chunk_margin_total_ns"] / max(counters["chunks_accepted"], 1)
    timing = counters["timing"]
    found = detections.drain()
    return {
        "drive": {"transport": transport, "record": record, "angle_deg": angle_deg, "duration_s": drive.duration,
                  "speed": speed,
                  "bodies": list(BODIES) if bodies else [], "wall_s": wall},
        "send_lateness_ms": {**_percentiles(lateness, 1e-6),
                             "chunk_period_ms": report.samples / report.chunks * spacing * 1e-6 / speed,
                             "lead_ms": lead * 1e3 / speed, "chunks": report.chunks},
        "host_to_controller_ms": {
            "mean": (lead * 1e9 - margin_mean) / speed * 1e-6 - lateness.mean() * 1e-6,
            "worst_bound": (lead * 1e9 - counters["chunk_margin_min_ns"]) / speed * 1e-6,
            "timesync_half_round_trip": _percentiles(round_trips / 2, 1e-6),
        },
        "controller_to_host_ms": {**_percentiles(status_latency, 1e-6), "statuses": len(received)},
        "accelerometer": {
            "samples_per_s": len(times) / (wall + 0.5) if batches else 0.0,
            "rate_hz": drive.rate * speed,
            "batches_lost": stats["accel_batches_lost"],
            "samples_in_stream": inside,
            "expected_in_stream": report.t_end_ns // spacing - math.ceil(report.t_start_ns / spacing) + 1,
        },
        "emulator": {key: timing[key] for key in ("tick_time_mean_us", "tick_time_p99_us", "tick_cpu_mean_us",
                                                    "tick_budget_us",
                                                    "real_time_factor", "batch_size_mean", "batch_size_max",
                                                    "lag_max_ms")},
        "tracking": {
            "surge_error_max_mm": float(surge_error.max()) * 1e3,
            "v_max_tau_mm": float(np.abs(drive.velocities[:, 0]).max()) * TAU * 1e3,
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
    p.add_argument("--lead", type=float, default=0.05, help="setpoint lead [s, controller time]")
    p.add_argument("--speed", type=float, default=1.0, help="emulator speed (controller time per real time)")
    p.add_argument("--no-bodies", action="store_true", help="no specimens on the plate")
    args = p.parse_args()
    print(json.dumps(run(args.transport, args.record, args.angle, args.lead, args.speed, not args.no_bodies), indent=1))


if __name__ == "__main__":
    main()
