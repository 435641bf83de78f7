"""A real small session file, the one the damaged-file and checksum tests start from."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.session import SessionLog

BODIES = [{"body_id": 1, "b": 0.10, "h": 0.50, "depth": 0.10, "mass": 4.0, "x": 0.0, "y": 0.0}]
"""The one body of each run [m, kg]."""


def write_small_session(path: Path, name: str) -> bytes:
    """Write at ``path`` a session named ``name`` of two completed runs of record ``suite:a`` at 5°, each with 100
    commanded poses, 3 s of 1 kHz plate acceleration, body 1's tilt, one overturn (+1 at 0.2 s) and one event;
    return the file's bytes."""
    sequence = {"name": name, "angles_deg": [5.0], "records": ["suite:a"], "repetitions": 1}
    log = SessionLog.create(path, {"table": {}}, sequence, "0.1.0+test")
    for plan in range(2):
        commanded = np.zeros((100, 7))
        commanded[:, 0] = np.arange(100) / 1000.0
        run = log.begin_run(plan, record="suite:a", scale_factor=0.5, angle_deg=5.0, commanded=commanded,
                            bodies=BODIES, sensors=["plate"])
        k = np.arange(3000)
        run.append_accel("plate", k / 1000.0, np.sin(np.column_stack([k, 2 * k, 3 * k]) / 100.0))
        run.append_tilt(1, k / 1000.0, 0.01 * np.sin(k / 50.0))
        run.add_detection(0.2, 1, +1, "sensor")
        run.add_event(0.0, "started")
        run.end("completed")
    log.close()
    return path.read_bytes()
