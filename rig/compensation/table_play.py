"""Playing drives on a table (any transport, ``drivers.controller``) as runs of a session file.

Each play is one run of the session (``SessionLog.begin_run``: the commanded trajectory, the table's feedback
recorded by :class:`~rig.orchestrator.recorder.RunRecorder`), with the run attributes ``compensation`` (``"identify"``
or ``"iterate"``) and ``iteration`` (0: the drive as prepared), and — for the iterations — its ``level_db`` (the
drive's scale against the target's) and the fall-line ``rms_error_pct`` and ``peak_error_pct`` against the target
at that level, set when the run ends. The table is tilted to the
drive's angle before (SET_TILT) and held there; the drives start and end at that tilt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drivers.controller import TableController
from rig.drive import Drive
from rig.orchestrator.orchestrator import LEAD, LINGER, missing_tail
from rig.orchestrator.recorder import RunRecorder
from rig.orchestrator.states import Progress

from .iteration import fall_line_errors
from .signals import base_accelerations, on_grid


class _Capture:
    """A run log that also keeps the accelerometer rows of one sensor (what the iteration needs at once)."""

    def __init__(self, run_log: Any, sensor: str) -> None:
        self._run_log = run_log
        self._sensor = sensor
        self.rows: list[np.ndarray] = []

    def append_accel(self, sensor: str, t: np.ndarray, xyz: np.ndarray) -> None:
        self._run_log.append_accel(sensor, t, xyz)
        if sensor == self._sensor:
            self.rows.append(np.column_stack([t, xyz]))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._run_log, name)


@dataclass
class TablePlayer:
    """Plays drives on ``table`` into the session ``log`` (module docstring); ``sensor`` the accelerometer id whose
    readings the iteration uses; ``bodies`` the session's body rows (``SessionLog.begin_run``); ``target`` the
    drive whose accelerations are the iteration's target (None for the identification)."""

    table: TableController
    log: Any
    url: str
    sensor: int = 0
    bodies: list[dict[str, Any]] = field(default_factory=list)
    target: Drive | None = None
    runs: list[str] = field(default_factory=list)
    """The session's run names, in the order played."""

    def tilt(self, angle: float, timeout: float = 120.0) -> None:
        """Arm the table (if needed) and tilt it to ``angle`` [rad]."""
        if self.table.status().state != "armed":
            self.table.arm()
        self.table.set_tilt(angle, timeout=timeout)

    def play(self, drive: Drive, role: str, iteration: int) -> np.ndarray:
        """Play ``drive`` as a run (``role`` ``"identify"``/``"iterate"``, its ``iteration``); the plate-frame specific
        force (n, 3) [m/s²] measured at the drive's samples. Raises RuntimeError when the table stops the stream or the
        accelerometer's samples stop short of the drive's end (the run then ends ``degraded``)."""
        name = str(self.sensor)
        run_log = self.log.begin_run(
            len(self.runs), record=drive.record, scale_factor=drive.scale_factor,
            angle_deg=math.degrees(drive.angle), commanded=drive.commanded, bodies=self.bodies, sensors=[name],
            attrs={"compensation": role, "iteration": iteration, "table_url": self.url, "rate": drive.rate,
                   "corner_frequency": drive.corner_frequency, "governing_axis": drive.governing.axis,
                   "governing_quantity": drive.governing.quantity})
        self.runs.append(run_log.name)
        capture = _Capture(run_log, name)
        recorder = RunRecorder(self.table, capture, {self.sensor: name}, [int(b["body_id"]) for b in self.bodies],
                               Progress(runs_total=1))
        try:
            report = self.table.stream(drive.t, drive.poses, lead=LEAD, on_start=recorder.start)
        except Exception as exc:
            recorder.finish(LINGER)
            run_log.end("aborted", reason=f"the table stopped the stream: {exc}")
            raise RuntimeError(f"run {run_log.name} ({role} {iteration}): the table stopped the stream: {exc}") \
                from exc
        t_end = float(drive.t[-1])
        recorder.finish(LINGER, until=t_end)
        missing = missing_tail(recorder.short_of(t_end), t_end)
        if missing:
            run_log.end("degraded", underruns=report.underruns, degraded="; ".join(missing))
            raise RuntimeError(f"run {run_log.name} ({role} {iteration}) cannot be measured: {'; '.join(missing)}")
        rows = np.concatenate(capture.rows)
        force = on_grid(rows, drive.t)
        extra: dict[str, Any] = {"underruns": report.underruns, "t_start_controller_ns": report.t_start_ns}
        if self.target is not None:
            level = drive.scale_factor / self.target.scale_factor
            extra["level_db"] = 20.0 * math.log10(level)
            _, extra["rms_error_pct"], extra["peak_error_pct"] = fall_line_errors(
                self.target, base_accelerations(force, drive.angle) / level)
        run_log.end("completed", **extra)
        return force

    def finish(self, timeout: float = 120.0) -> None:
        """Home and disarm."""
        self.table.home(timeout=timeout)
        if self.table.status().state == "armed":
            self.table.disarm()
