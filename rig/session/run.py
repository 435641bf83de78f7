"""`RunLog`: the run being recorded. Appends go to the run's `BlockWriter` (no disk I/O in the caller);
`RunLog.end` stops it and lets its session (a `RunOwner`: `rig.session.log.SessionLog`) commit the run's final
attributes."""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np

from analysis.table.sensors import clipped_rows

from . import failpoints, schema
from .errors import SessionError
from .runinfo import RunInfo
from .writer import BlockWriter, WriterStats


class RunOwner(Protocol):
    """What a run needs of its session (`rig.session.log.SessionLog`): where it is, the extra run attributes
    checked as stored, and the commit of a run's final status and attributes."""

    @property
    def path(self) -> Path:
        """The session file (named in every error)."""

    def checked_run_attrs(self, attrs: Mapping[str, Any] | None) -> dict[str, Any]:
        """Extra run attributes as stored; `rig.session.errors.SessionError` on a reserved name or a bad value."""

    def finish_run(self, info: RunInfo, status: str, attrs: Mapping[str, Any]) -> RunInfo:
        """Commit the run's final ``status`` and ``attrs`` (after its SWMR file is closed); the run as ended."""


def _rows(t: np.ndarray, values: np.ndarray, width: int, what: str) -> np.ndarray:
    """(k, 1 + width) float64 rows [t, values…]; SessionError on a shape mismatch."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1 and len(t) == 1 and values.shape[0] == width:
        values = values.reshape(1, width)
    if values.shape != (len(t), width):
        raise SessionError(f"{what}: got t {t.shape} and values {values.shape}; expected t (k,) and values "
                           f"(k, {width})")
    rows = np.empty((len(t), width + 1))
    rows[:, 0] = t
    rows[:, 1:] = values
    return rows


class RunLog:
    """The run being recorded; obtained from `SessionLog.begin_run`. Appends are thread-safe and never wait for
    the disk."""

    def __init__(self, session: RunOwner, info: RunInfo, sensors: Sequence[str], body_ids: Sequence[int],
                 h5: h5py.File, writer: BlockWriter, ranges: Mapping[str, float] | None = None,
                 tilt_ranges: Mapping[int, float] | None = None) -> None:
        self._session = session
        self.info = info
        self.sensors = tuple(sensors)
        self._h5 = h5
        self._writer = writer
        self._ended = False
        self._lock = threading.Lock()  # an append racing `end` is either written or refused, never dropped
        self._accel_keys = {sensor: f"accel/{sensor}" for sensor in sensors}
        self._tilt_keys = {body_id: f"tilt/{body_id}" for body_id in body_ids}
        self._ranges = dict(ranges or {})
        self.clipped = dict.fromkeys(self._ranges, 0)
        """Samples (rows) per sensor with a sheet that reached its full scale on some axis (run attribute
        ``clipped``, JSON, at the end)."""
        self._tilt_ranges = dict(tilt_ranges or {})
        self.tilt_clipped = {body_id: 0 for body_id in self._tilt_ranges}
        """Samples per body whose tilt sensor has a sheet that reached its full scale (run attribute
        ``tilt_clipped``, JSON ``{"BODY_ID": samples}``, at the end)."""

    @property
    def name(self) -> str:
        """Group name, ``"0001"``…"""
        return self.info.name

    @property
    def plan_index(self) -> int:
        return self.info.plan_index

    @property
    def attempt(self) -> int:
        return self.info.attempt

    @property
    def stats(self) -> WriterStats:
        """The writer's counters (rows per dataset, flushes, worst append-to-disk latency [s])."""
        return self._writer.stats

    def _put(self, key: str, rows: np.ndarray) -> None:
        with self._lock:
            if self._ended:
                raise SessionError(f"{self._session.path}: run {self.name} has ended; nothing more can be appended")
            if self._writer.error is not None:
                raise SessionError(f"{self._session.path}: run {self.name}: the writer failed "
                                   f"({self._writer.error!r})") from self._writer.error
            self._writer.put(key, rows)

    def append_accel(self, sensor: str, t: np.ndarray, xyz: np.ndarray) -> None:
        """Accelerometer samples: ``t`` (k,) [s], ``xyz`` (k, 3) [m/s², plate frame]. A sample at or beyond the
        sensor's full scale (its sheet's range, ±) on any axis is counted as clipped; the first of the run adds the
        event ``clipped: …``."""
        key = self._accel_keys.get(sensor)
        if key is None:
            raise SessionError(f"{self._session.path}: run {self.name}: unknown sensor {sensor!r}; expected one "
                               f"of {list(self.sensors)}")
        rows = _rows(t, xyz, 3, f"accel {sensor!r}")
        self._put(key, rows)
        full_scale = self._ranges.get(sensor)
        if full_scale is None:
            return
        clipped = clipped_rows(rows[:, 1:], full_scale)
        if not len(clipped):
            return
        first = self.clipped[sensor] == 0
        self.clipped[sensor] += len(clipped)
        if first:
            row = int(clipped[0])
            column = 1 + int(np.argmax(np.abs(rows[row, 1:]) >= full_scale))
            self.add_event(float(rows[row, 0]), f"clipped: accelerometer {sensor} {schema.ACCEL_COLUMNS[column]} = "
                                                f"{rows[row, column]:.4g} m/s² at its full scale ±{full_scale:.4g} "
                                                "m/s²")

    def append_tilt(self, body_id: int, t: np.ndarray, angle: np.ndarray) -> None:
        """A body's tilt-sensor samples: ``t`` (k,) [s], ``angle`` (k,) [rad, relative to the plate, > 0 towards
        the low side]. A sample at or beyond the sensor's full scale (its sheet's range, ±) is counted as clipped;
        the first of the run adds the event ``clipped: …``."""
        key = self._tilt_keys.get(body_id)
        if key is None:
            raise SessionError(f"{self._session.path}: run {self.name}: body {body_id!r} is not on the plate; "
                               f"expected one of {list(self._tilt_keys)}")
        rows = _rows(t, np.reshape(angle, (-1, 1)), 1, f"tilt of body {body_id}")
        self._put(key, rows)
        full_scale = self._tilt_ranges.get(body_id)
        if full_scale is None:
            return
        clipped = clipped_rows(rows[:, 1:], full_scale)
        if not len(clipped):
            return
        if self.tilt_clipped[body_id] == 0:
            row = int(clipped[0])
            self.add_event(float(rows[row, 0]), f"clipped: tilt sensor of body {body_id} angle = "
                                                f"{rows[row, 1]:.4g} rad at its full scale ±{full_scale:.4g} rad "
                                                f"({math.degrees(full_scale):.4g}°)")
        self.tilt_clipped[body_id] += len(clipped)

    def append_pose(self, t: np.ndarray, pose: np.ndarray) -> None:
        """Measured table pose: ``t`` (k,) [s], ``pose`` (k, 6): surge, sway, heave [m], roll, pitch, yaw [rad]."""
        self._put("pose", _rows(t, pose, 6, "pose"))

    def append_following_error(self, t: np.ndarray, errors: np.ndarray) -> None:
        """Each leg's following error: ``t`` (k,) [s], ``errors`` (k, 6) [m, commanded minus measured length], legs
        1…6."""
        self._put("following_error", _rows(t, errors, 6, "following error"))

    def append_commanded(self, t: np.ndarray, pose: np.ndarray) -> None:
        """More commanded trajectory (for drives streamed in pieces), columns as `append_pose`."""
        self._put("commanded", _rows(t, pose, 6, "commanded"))

    def add_detection(self, t: float, body_id: int, direction: int, source: str) -> None:
        """An overturn: time [s], body, direction (+1 low side, −1 high side, 0 none), ``"sensor"``/``"operator"``."""
        if direction not in (-1, 0, 1):
            raise SessionError(f"detection direction {direction!r}; expected +1, -1 or 0")
        if source not in schema.DETECTION_SOURCES:
            raise SessionError(f"detection source {source!r}; expected one of {list(schema.DETECTION_SOURCES)}")
        row = np.array([(t, body_id, direction, schema.fixed_text(source, schema.SOURCE_LEN))], schema.DETECTION)
        self._put("detections", row)

    def add_fault(self, t: float, name: str, detail: str) -> None:
        """A fault reported by the table or the rig at ``t`` [s]."""
        row = np.array([(t, schema.fixed_text(name, schema.NAME_LEN), schema.fixed_text(detail, schema.TEXT_LEN))],
                       schema.FAULT)
        self._put("faults", row)

    def add_event(self, t: float, text: str) -> None:
        """A log line at ``t`` [s]: state change, operator answer, pause/abort request…"""
        self._put("events", np.array([(t, schema.fixed_text(text, schema.TEXT_LEN))], schema.EVENT))

    def end(self, status: str, **attrs: Any) -> RunInfo:
        """Flush everything, close the SWMR file and set ``status``, ``ended`` and ``attrs`` (in one atomic change;
        ``attrs`` may also replace extra attributes given to `SessionLog.begin_run`)."""
        if status not in schema.FINAL_STATUSES:
            raise SessionError(f"run status {status!r}; expected one of {list(schema.FINAL_STATUSES)}")
        extra = self._session.checked_run_attrs(attrs)
        if self._ranges:
            extra["clipped"] = json.dumps(self.clipped)
        if self._tilt_ranges:
            extra["tilt_clipped"] = json.dumps({str(body): count for body, count in self.tilt_clipped.items()})
        with self._lock:
            if self._ended:
                raise SessionError(f"{self._session.path}: run {self.name} has already ended ({self.info.status})")
            self._ended = True
        self._writer.stop()
        error = self._writer.error
        try:
            self._h5.close()
        except Exception as exc:  # reported below; the run still gets its status
            error = error or exc
        failpoints.hit("end:swmr-closed")
        if error is not None:
            extra["writer_error"] = repr(error)[:500]
        info = self._session.finish_run(self.info, status, extra)
        self.info = info
        if error is not None:
            raise SessionError(f"{self._session.path}: run {self.name}: samples may be missing, the writer failed "
                               f"({error!r}); status set to {status!r}")
        return info
