"""The emulated controller's own limit detectors: the abort levels the host downloaded
(``analysis.table.controller_limits``), evaluated on every tick's accelerometer sample with the host's
persistence semantics (``analysis.table.limit_detectors.first_trip``: that many samples in a row past the level).

:class:`LimitLevels` is armed for one stream: START_STREAM starts its counts afresh, and the stream's end (any:
its last sample, a stop, a fault) clears the levels, so a level never outlives the run it was downloaded for.
The first level passed trips (one trip a stream: the table is stopping after it).
"""

from __future__ import annotations

import numpy as np

from analysis.table.controller_limits import ControllerLevel, ControllerTrip
from analysis.table.limit_detectors import first_trip

_AXES = {"accel.x": 0, "accel.y": 1, "accel.z": 2}


class LimitLevels:
    """The levels downloaded for the next stream and their consecutive counts per accelerometer."""

    def __init__(self) -> None:
        self.levels: list[ControllerLevel] = []
        self._carry: dict[tuple[int, int], int] = {}  # (level index, sensor) → samples past it in a row so far
        self._tripped = False

    def add(self, level: ControllerLevel) -> None:
        """Download one more level (a repeated one replaces nothing: both are evaluated, the same trip)."""
        self.levels.append(level)

    def clear(self) -> None:
        """Forget every level (SET_LIMIT with code 0, the stream's end)."""
        self.levels.clear()
        self.restart()

    def restart(self) -> None:
        """A stream starts: counts from zero, nothing tripped."""
        self._carry.clear()
        self._tripped = False

    def accel(self, times: np.ndarray, force: np.ndarray) -> ControllerTrip | None:
        """The accelerometers' samples at ``times`` (k,) [ns, controller time], ``force`` (k, m, 3) [m/s²]: the
        earliest trip among the levels (None: none, or one already tripped)."""
        if self._tripped or not self.levels or not len(times):
            return None
        found: list[tuple[int, int, int]] = []  # (sample index, sensor, level index)
        for k, level in enumerate(self.levels):
            values = force[:, :, _AXES[level.channel]]
            past = values > level.threshold if level.side == "abort_high" else values < level.threshold
            for sensor in range(force.shape[1]):
                index, self._carry[k, sensor] = first_trip(past[:, sensor], self._carry.get((k, sensor), 0),
                                                           level.persistence)
                if index is not None:
                    found.append((index, sensor, k))
        if not found:
            return None
        index, sensor, k = min(found)
        self._tripped = True
        level = self.levels[k]
        return ControllerTrip(int(times[index]), sensor, float(force[index, sensor, _AXES[level.channel]]), level)
