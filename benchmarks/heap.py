"""Benchmark: the garbage collector's full passes in the host process, with and without the link's heap hold.

A full pass (generation 2) holds the GIL for its whole duration, so while a table link is open it stops the
heartbeat, receive and streaming threads (``drivers/heap.py``). This measures, in one process:

1. ``full_pass_ms``: one full pass (``gc.collect()``) over the heap of ``rig`` with its analysis, session log,
   emulator and the three transports imported, plus ``--extra`` long-lived containers standing in for a larger
   host (a service that holds sessions, a test session: this project's own holds ~270k objects), as it is without
   a hold and while a :class:`drivers.heap.HeapHold` holds (median of ``--repeat``);
2. ``stream``: the longest collector pause of any generation seen (``gc.callbacks``) while that heap's process
   streams a FEMA drive excerpt to the emulator at ``--speed max`` over MAVLink on loopback, through
   ``open_table`` (so under the driver's own hold), with the count of full passes.

The watchdog the pauses compete with: the controller's 100 ms heartbeat watchdog and the stream's 75 ms lead.

Usage: ``python benchmarks/heap.py [--extra N] [--repeat N] [--no-stream]``; prints one JSON object.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import statistics
import tempfile
import time
from pathlib import Path

import drivers.canopen
import drivers.mavlink
import drivers.zenoh  # noqa: F401
import rig.cli
import rig.orchestrator.orchestrator  # noqa: F401
import sim_table.process  # noqa: F401
from drivers.controller import open_table
from drivers.heap import HeapHold
from protocols.signing_key import write_signing_key
from rig.drive.prepare import prepare_drive
from rig.emulator import EmulatorProcess
from rig.records import load_record


def full_pass_ms(repeat: int) -> float:
    """Median time [ms] of ``repeat`` full collections of the heap as it is."""
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        gc.collect()
        times.append((time.perf_counter() - started) * 1e3)
    return statistics.median(times)


class PauseWatch:
    """Every collector pause while installed: the longest [ms] per generation and the count of full passes."""

    def __init__(self) -> None:
        self.longest = [0.0, 0.0, 0.0]
        self.full_passes = 0
        self._started = 0

    def __call__(self, phase: str, info: dict[str, int]) -> None:
        if phase == "start":
            self._started = time.perf_counter_ns()
            return
        generation = info["generation"]
        self.longest[generation] = max(self.longest[generation], (time.perf_counter_ns() - self._started) * 1e-6)
        self.full_passes += generation == 2


def stream_pauses(directory: Path) -> dict[str, object]:
    """Stream 16 s of NORTHR/MUL009 at 5° to an emulator at --speed max while :class:`PauseWatch` watches."""
    key_file = directory / "rig.key"
    write_signing_key(key_file)
    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=math.radians(5))
    drive_t, poses = drive.t[:16_000], drive.poses[:16_000]
    emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", "--body", "0.2x0.6", "--speed", "max",
                                     key_file=key_file)
    watch = PauseWatch()
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            gc.callbacks.append(watch)
            garbage = [[k] for k in range(200_000)]  # the host's own work meanwhile: containers made and dropped
            try:
                report = table.stream(drive_t, poses, lead=0.075)
            finally:
                gc.callbacks.remove(watch)
            del garbage
            table.disarm()
    finally:
        counters = emulator.stop()
    return {"seconds_of_drive": report.duration, "underruns": report.underruns, "emulator_state": counters["state"],
            "longest_pause_ms": {f"generation_{g}": round(ms, 2) for g, ms in enumerate(watch.longest)},
            "full_passes": watch.full_passes}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extra", type=int, default=200_000, help="long-lived containers added to the heap")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-stream", action="store_true", help="only the full-pass figures")
    args = parser.parse_args()
    ballast = [[k] for k in range(args.extra)]  # noqa: F841  (kept alive: the larger host)
    objects = len(gc.get_objects())
    unheld = full_pass_ms(args.repeat)
    hold = HeapHold()
    hold.hold()
    held = full_pass_ms(args.repeat)
    hold.release()
    out: dict[str, object] = {
        "figure": "full garbage-collection pass in the host process [ms], with the link's heap hold",
        "unit": "ms",
        "compared_with": "the same pass over the same heap without the hold, measured in this run",
        "tracked_objects": objects,
        "full_pass_ms": {"without_hold": round(unheld, 3), "with_hold": round(held, 4)},
        "heartbeat_watchdog_ms": 100.0,
    }
    if not args.no_stream:
        with tempfile.TemporaryDirectory() as directory:
            out["stream"] = stream_pauses(Path(directory))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
