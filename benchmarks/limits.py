"""Benchmark: the latency of a limit detector's stop, from the crossing to the table stopping, in the table's own
time, against one controller status period (the goal). Prints one JSON object.

Each case plays a one-run sequence (a FEMA near-field record on the emulated table over MAVLink, one Table V body)
whose ``[limit_detectors.accel.x]`` has ``abort_high_g = 0.05`` (controlled stop), by two paths: ``controller``
(the level downloaded to the controller, which evaluates it on every tick and starts its stop ramp itself) and
``host`` (the host's detector alone: it trips on the sample once its batch arrives and sends STOP). The latency is
what the run's session file says (``rig/orchestrator/recorder.py``): from the time of the sample that tripped to
the first status showing the table ``stopping`` — the state change's own tick —, both controller time. Cases:
each path with the emulator at real time (``--speed 1``: the table's time is the wall clock's) and in virtual
time (``--speed max``: the table runs ahead of the host up to the setpoints it holds, and takes a host message at
its next batch of ticks), ``--repeats`` each; reported per case the latencies [ms], their median and largest,
beside the goal (the emulator's status period, ``sim_table.process.STATUS_PERIOD_NS``) and the load average.

Usage: ``python benchmarks/limits.py [--repeats 3] [--speeds 1,max] [--paths controller,host]``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys
import tempfile
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from protocols.signing_key import write_signing_key
from rig.emulator import EmulatorProcess, specimen_flags
from rig.orchestrator import Orchestrator
from rig.sequence import load_sequence
from rig.session import SessionLog, read_session
from sim_table.process import STATUS_PERIOD_NS

SEQUENCE = """\
name = "limits-benchmark"
angles_deg = [0]
records = [{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 3.5] }]

[drive]
corner_hz = 1.0
settle_s = 0.3

[operator]
confirm_before_run = false

[[bodies]]
table5 = 5
x = 0.0
y = 0.0

[limit_detectors.accel.x]
abort_high_g = 0.05
"""

_LATENCY = re.compile(r"the table was stopping ([0-9.]+) ms after the crossing")


def latency_ms(directory: Path, speed: str, path_name: str, key_file: Path) -> float | None:
    """One play at ``speed`` by ``path_name`` (``controller`` or ``host``): the stop's latency [ms, table time],
    or None when the run was not stopped."""
    path = directory / "sequence.toml"
    path.write_text(SEQUENCE)
    sequence = load_sequence(path)
    session = directory / f"session-{speed}.h5"
    log = SessionLog.create(session, rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                            software_version="benchmark")
    emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", *specimen_flags(sequence.bodies), "--speed", speed,
                                     key_file=key_file)
    try:
        orchestrator = Orchestrator(sequence, emulator.url, log, table_options={"key_file": str(key_file)},
                                    controller_limits=path_name == "controller")
        worker = threading.Thread(target=orchestrator.run, daemon=True)
        worker.start()
        worker.join(300)
    finally:
        emulator.stop()
        log.close()
        session_runs = read_session(session)["runs"]
        session.unlink()
    for event in session_runs[0]["events"] if session_runs else []:
        found = _LATENCY.search(event["text"])
        if found:
            return float(found.group(1))
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--speeds", default="1,max")
    parser.add_argument("--paths", default="controller,host")
    args = parser.parse_args()
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        key_file = directory / "rig.key"
        write_signing_key(key_file)
        for path_name in args.paths.split(","):
            for speed in args.speeds.split(","):
                values = [latency_ms(directory, speed, path_name, key_file) for _ in range(args.repeats)]
                measured = [v for v in values if v is not None]
                cases.append({"path": path_name, "speed": speed, "latency_ms": values,
                              "median_ms": statistics.median(measured) if measured else None,
                              "max_ms": max(measured) if measured else None})
    goal = STATUS_PERIOD_NS * 1e-6
    print(json.dumps({"figure": "limit stop latency (crossing to the start of the table's stop ramp)",
                      "unit": "ms (table time)", "goal_ms": goal, "goal": "one controller status period",
                      "cases": [{**case, "within_goal": case["max_ms"] is not None and case["max_ms"] <= goal}
                                for case in cases],
                      "load_average": os.getloadavg()[0]}, indent=2))


if __name__ == "__main__":
    main()
