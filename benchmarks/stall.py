"""Benchmark: the lab host stalls mid-stream (SIGSTOP, then SIGCONT) for 0.1, 0.5 and 0.9 × the lead, at 1x on
each transport whose controller buffers setpoints (MAVLink, zenoh); what the table did. Prints one JSON object.

Each case runs the emulator (its own process, real time, one Table V body on the plate) and a **host process**
(this script with ``--host URL``) that connects, tilts and streams a prepared FEMA drive with the rig TOML's
default lead (``analysis.table.link``: 1 s) and records the plate accelerometer. This process stops the host
process with SIGSTOP one third into the drive, for the stall, and lets it go on (SIGCONT). Reported per case,
each beside what it is compared with:

* ``underruns`` and ``samples_late`` (the emulator's counters) — against 0, which a stall shorter than the lead
  must give; ``outcome``: ``completed`` (the stream played to its end) or what stopped it;
* ``peak_accel_m_s2``: the largest measured fall-line acceleration change from rest, against the commanded
  drive's (``commanded_peak_accel_m_s2``, its poses' second difference): a jump would show as a spike far above it;
* ``peak_jerk_m_s3``: the largest jerk of the measured fall-line acceleration low-passed at 30 Hz (the
  accelerometer's noise differentiated would swamp the raw one), against the commanded drive's, low-passed the
  same way;
* ``stop_to_decelerating_ms`` (once per transport, without a stall): from the host sending STOP mid-stream to the
  first status showing the table ``stopping`` (the buffer flushed and the plate decelerating) — against the
  lead, which the buffer would otherwise still play.

CANopen is not run: its master, in the host process, *is* the controller (it plays the drive itself and sends
each leg drive a target per SYNC), so a stalled host stops the SYNC; the emulated drives hold their target delay
of targets (60 ms by default, up to 2 s with the listen URL's ``target_delay=S``), and cyclic synchronous position
tolerates no longer host stall (``docs/table-controller.md``, stall tolerance per transport).

Usage: ``python benchmarks/stall.py [--transport mavlink|zenoh|all] [--fractions 0.1,0.5,0.9]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal as dsp

from analysis.table.link import LinkSettings
from drivers.controller import StreamAbortedError, TableError, open_table
from protocols.signing_key import write_signing_key
from rig.emulator import EmulatorProcess
from rig.sequence import load_sequence

LISTEN = {"mavlink": "mavlink://127.0.0.1:0", "zenoh": "zenoh://127.0.0.1:0/stall"}
QUICK = Path(__file__).resolve().parents[1] / "examples" / "quick.toml"
ANGLE_DEG = 4.0
"""The plan entry played: the quick sequence's first record at 4° (the Rinaldi record, 5 s, scaled to Table IV)."""
BODY = "0.039x0.2@0,0;depth=0.081;mass=0.36"
LOWPASS_HZ = 30.0
"""Low-pass corner of the jerk comparison [Hz]."""
RATE = 1000.0


def drive() -> Any:
    """The prepared drive every case plays (:data:`ANGLE_DEG`): it starts and ends at rest at the tilt."""
    sequence = load_sequence(QUICK)
    run = next(r for r in sequence.plan() if r.angle_deg == ANGLE_DEG and r.record_index == 0)
    return sequence.prepare(run)


def commanded_fall_line(poses: np.ndarray) -> np.ndarray:
    """The drive's surge acceleration [m/s²] at 1 kHz (second difference)."""
    return np.gradient(np.gradient(poses[:, 0], 1 / RATE), 1 / RATE)


def jerk(acc: np.ndarray) -> float:
    """Largest |d/dt| [m/s³] of ``acc`` [m/s², 1 kHz] low-passed at :data:`LOWPASS_HZ` (zero phase)."""
    sos = dsp.butter(4, LOWPASS_HZ, fs=RATE, output="sos")
    return float(np.abs(np.diff(dsp.sosfiltfilt(sos, acc)) * RATE).max())


# ----- the host process -------------------------------------------------------------------------------------


def host(url: str, key_file: str, stop_mid: bool) -> dict[str, Any]:
    """Connect, tilt, stream the drive (recording the plate's fall-line specific force), or with ``stop_mid``
    send STOP 2 s into it and time the table's reaction."""
    d = drive()
    lead = LinkSettings().lead_s
    result: dict[str, Any] = {}
    with open_table(url, key_file=key_file) as table:
        table.arm()
        table.set_tilt(math.radians(ANGLE_DEG))
        accel = table.accelerations()
        print("streaming", flush=True)
        if stop_mid:
            import threading

            def stop_later() -> None:
                time.sleep(lead + 2.0)
                statuses = table.statuses()
                sent = time.monotonic_ns()
                table.stop()
                for status in statuses:
                    if status.state == "stopping":
                        result["stop_to_decelerating_ms"] = (status.host_ns - sent) * 1e-6
                        break
                statuses.close()

            threading.Thread(target=stop_later, daemon=True).start()
        try:
            report = table.stream(d.t, d.poses, lead=lead)
            result["outcome"] = "completed"
            start = report.t_start_ns
        except StreamAbortedError as exc:
            result["outcome"] = str(exc)
            start = exc.report.t_start_ns
        except TableError as exc:
            result["outcome"] = f"table error: {exc}"
            start = None
        time.sleep(0.3)
        table.wait_for_status(lambda s: s.state in ("armed", "faulted"), 30)
        if table.status().state == "armed":
            table.home()
            table.disarm()  # at rest and disarmed before the link closes: no watchdog stop after the host left
        batches = accel.drain()
        accel.close()
        if batches and start is not None:
            t = np.concatenate([b.times_ns() for b in batches])
            fx = np.concatenate([b.samples[:, 0] for b in batches])
            inside = (t >= start) & (t <= start + round(d.duration * 1e9))
            fx = fx[inside]
            rest = float(np.median(fx[:200]))
            result["peak_accel_m_s2"] = float(np.abs(fx - rest).max())
            result["peak_jerk_m_s3"] = jerk(fx - rest)
    return result


# ----- one case ---------------------------------------------------------------------------------------------


def case(transport: str, stall: float, key: Path, stop_mid: bool = False) -> dict[str, Any]:
    """One stall of ``stall`` s (0: none) of the host process mid-stream on ``transport``."""
    with EmulatorProcess.start(LISTEN[transport], "--body", BODY, key_file=key) as emulator:
        host_proc = subprocess.Popen([sys.executable, __file__, "--host", emulator.url, "--key-file", str(key)]
                                     + (["--stop-mid"] if stop_mid else []),
                                     stdout=subprocess.PIPE, text=True)
        assert host_proc.stdout is not None
        line = host_proc.stdout.readline()
        if line.strip() != "streaming":
            host_proc.kill()
            raise RuntimeError(f"the host process did not start streaming: {line!r}")
        d_duration = drive().duration
        if stall > 0:
            time.sleep(LinkSettings().lead_s + d_duration / 3)
            os.kill(host_proc.pid, signal.SIGSTOP)
            time.sleep(stall)
            os.kill(host_proc.pid, signal.SIGCONT)
        out, _ = host_proc.communicate(timeout=120)
        counters = emulator.stop()
    result = json.loads(out.strip().splitlines()[-1])
    result.update(underruns=counters["underruns"], samples_late=counters["samples_late"],
                  watchdog_stops=counters["watchdog_stops"], faults_raised=counters["faults_raised"])
    return result


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--transport", choices=(*LISTEN, "all"), default="all")
    p.add_argument("--fractions", default="0.1,0.5,0.9", help="stalls as fractions of the lead")
    p.add_argument("--host", help=argparse.SUPPRESS)
    p.add_argument("--key-file", help=argparse.SUPPRESS)
    p.add_argument("--stop-mid", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.host:
        print(json.dumps(host(args.host, args.key_file, args.stop_mid)), flush=True)
        return
    lead = LinkSettings().lead_s
    fractions = [float(f) for f in args.fractions.split(",")]
    d = drive()
    commanded = commanded_fall_line(d.poses)
    out: dict[str, Any] = {
        "benchmark": "stall", "lead_s": lead, "watchdog_s": LinkSettings().watchdog_s,
        "drive": f"examples/quick.toml's first record at {ANGLE_DEG:g} deg, {d.duration:.1f} s",
        "commanded_peak_accel_m_s2": float(np.abs(commanded).max()),
        "commanded_peak_jerk_m_s3": jerk(commanded),
        "compared_with": "underruns and samples_late against 0 below the lead; measured peak acceleration and "
                         "jerk against the commanded drive's; stop reaction against the lead",
        "transports": {},
    }
    with tempfile.TemporaryDirectory() as scratch:
        key = Path(scratch) / "key"
        write_signing_key(key)
        for transport in LISTEN if args.transport == "all" else (args.transport,):
            cases = {f"{f:g}x_lead": case(transport, f * lead, key) for f in fractions}
            stop = case(transport, 0.0, key, stop_mid=True)
            out["transports"][transport] = {"stalls": cases,
                                            "stop_to_decelerating_ms": stop.get("stop_to_decelerating_ms")}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
