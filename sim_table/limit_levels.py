"""The emulated controller's own limit detectors: the abort levels the host downloaded
(``analysis.table.controller_limits``), evaluated with the host's persistence semantics and the host's code
(``analysis.table.limit_detectors``: ``first_trip``, ``is_past``, ``StatusVelocity``): the ``accel.*`` levels on
every tick's accelerometer sample, the ``pose.*``, ``velocity.*`` and ``leg.following_error`` levels on the
values of every status the controller sends (its measured pose, the velocity between consecutive statuses, each
leg's following error), so a persistence counts what the host counts.

:class:`LimitLevels` is armed for one stream: START_STREAM starts its counts afresh, and the stream's end (any:
its last sample, a stop, a fault) clears the levels, so a level never outlives the run it was downloaded for.
The first level passed trips (one trip a stream: the table is stopping after it).
"""

from __future__ import annotations

import numpy as np

from analysis.table.controller_limits import ACCEL_CHANNELS, ControllerLevel, ControllerTrip
from analysis.table.limit_detectors import POSE_AXES, StatusVelocity, first_trip, is_past

_AXES = {"accel.x": 0, "accel.y": 1, "accel.z": 2}


class LimitLevels:
    """The levels downloaded for the next stream and their consecutive counts per sensor."""

    def __init__(self) -> None:
        self.levels: list[ControllerLevel] = []
        self._carry: dict[tuple[int, int], int] = {}  # (level index, sensor) → samples past it in a row so far
        self._tripped = False
        self._velocity = StatusVelocity()

    def add(self, level: ControllerLevel) -> None:
        """Download one more level (a repeated one replaces nothing: both are evaluated, the same trip)."""
        self.levels.append(level)

    def clear(self) -> None:
        """Forget every level (SET_LIMIT with code 0, the stream's end)."""
        self.levels.clear()
        self.restart()

    def restart(self) -> None:
        """A stream starts: counts from zero, nothing tripped, no status before."""
        self._carry.clear()
        self._tripped = False
        self._velocity = StatusVelocity()

    def _first(self, series: dict[str, tuple[np.ndarray, np.ndarray, int]]) -> ControllerTrip | None:
        """The earliest trip of the levels on ``series``: channel → (times (k,) [ns], values (k, m) [SI], the
        first column's sensor number); marks it tripped."""
        if self._tripped:
            return None
        found: list[tuple[int, int, int, float]] = []  # (time, sensor, level index, value)
        for k, level in enumerate(self.levels):
            if level.channel not in series:
                continue
            times, values, first = series[level.channel]
            if not len(times):
                continue
            past = is_past(values, level.threshold, level.side)
            for column in range(values.shape[1]):
                sensor = first + column
                index, self._carry[k, sensor] = first_trip(past[:, column], self._carry.get((k, sensor), 0),
                                                           level.persistence)
                if index is not None:
                    found.append((int(times[index]), sensor, k, float(values[index, column])))
        if not found:
            return None
        t_ns, sensor, k, value = min(found)
        self._tripped = True
        return ControllerTrip(t_ns, sensor, value, self.levels[k])

    def batch(self, times: np.ndarray, force: np.ndarray, status_times: np.ndarray | None = None,
              pose: np.ndarray | None = None, following: np.ndarray | None = None) -> ControllerTrip | None:
        """A batch of ticks: the accelerometers' samples at ``times`` (k,) [ns, controller time], ``force`` (k, m, 3)
        [m/s²]; the statuses sent at ``status_times`` (j,) [ns] with the measured ``pose`` (j, 6) (m, rad) and
        each leg's ``following`` error (j, 6) [m] (call it for every status of the stream, in order: the velocity
        is between consecutive ones). The earliest trip among the levels (None: none, or one already tripped)."""
        series: dict[str, tuple[np.ndarray, np.ndarray, int]] = {
            channel: (times, force[:, :, axis], 0) for channel, axis in _AXES.items() if channel in ACCEL_CHANNELS}
        if status_times is not None and pose is not None and following is not None:
            t_velocity, velocity = self._velocity.feed(status_times.astype(float), pose)
            series["leg.following_error"] = (status_times, following, 1)
            for k, axis in enumerate(POSE_AXES):
                series[f"pose.{axis}"] = (status_times, pose[:, k:k + 1], 0)
                series[f"velocity.{axis}"] = (t_velocity.astype(np.int64), velocity[:, k:k + 1] * 1e9, 0)
        return self._first(series) if self.levels else None

    def accel(self, times: np.ndarray, force: np.ndarray) -> ControllerTrip | None:
        """:meth:`batch` with no statuses."""
        return self.batch(times, force)
