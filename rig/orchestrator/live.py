"""The live tap: what a display needs of the running test, decimated and bounded, for the service's live telemetry
(``rig.service.telemetry.LivePublisher``) and the operator's console (``rig.console``).

The orchestrator and its run recorder put into it from their own threads and never wait: every item goes into a
``deque`` with a fixed length, so when nobody drains it (``rig run`` without a console) the oldest items are
dropped and the orchestrator pays one append per item. Items are plain JSON types:

- ``("run", header)`` when a run begins: the run (plan index, record, angle [°], scale factor, duration [s], rate
  [Hz]), the session's plan, the bodies on the plate, the table time of the runs after it [s], and the commanded
  fall-line acceleration decimated to :data:`DISPLAY_RATE` (``t`` [s], ``a`` [m/s²]);
- ``("accel", t, a)``: measured fall-line acceleration, block means of :data:`DISPLAY_RATE`;
- ``("pose", t, pose)``: the table's measured pose (surge, sway, heave [m], roll, pitch, yaw [rad]);
- ``("detection", t, body_id, direction)`` and ``("fault", t, name, detail)``.

Times are the session file's run times: seconds from the drive's first sample. The **fall-line acceleration** is
plate x (+x downhill): measured, the accelerometer's plate-x specific force minus its reading at rest (the tilt's
gravity component −g sin β); commanded, the drive's surge acceleration × cos β (its component along the tilted
plate).
"""

from __future__ import annotations

import collections
import math
import threading
from typing import Any

import numpy as np

DISPLAY_RATE = 50.0
"""Samples per second of the decimated acceleration series [Hz]."""

CAPACITY = 4096
"""Items the tap holds when nobody drains it (about 40 s of accelerations and poses)."""


def block_means(t: np.ndarray, a: np.ndarray, rate: float, display_rate: float = DISPLAY_RATE
                ) -> tuple[list[float], list[float]]:
    """``(t, a)`` decimated to about ``display_rate`` by means over blocks of round(rate / display_rate) samples
    (a trailing partial block kept as its own mean)."""
    block = max(1, round(rate / display_rate))
    n = len(t)
    edges = np.arange(0, n, block)
    if n == 0:
        return [], []
    counts = np.diff(np.append(edges, n))
    return ((np.add.reduceat(t, edges) / counts).tolist(), (np.add.reduceat(a, edges) / counts).tolist())


class LiveTap:
    """The bounded, non-blocking feed of a running session's display data (module docstring)."""

    def __init__(self, capacity: int = CAPACITY) -> None:
        self._items: collections.deque[tuple[Any, ...]] = collections.deque(maxlen=capacity)
        self._lock = threading.Lock()
        self._carry: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.header: dict[str, Any] | None = None
        self.puts = 0

    def put(self, *item: Any) -> None:
        """One item (module docstring); the oldest is dropped when full."""
        self._items.append(item)
        self.puts += 1

    def begin_run(self, header: dict[str, Any]) -> None:
        """A run begins: its header (module docstring) replaces the last one; the decimation starts afresh."""
        with self._lock:
            self.header = header
            self._carry.clear()
        self.put("run", header)

    def accel(self, sensor: int, t: np.ndarray, a: np.ndarray) -> None:
        """Measured fall-line acceleration of ``sensor`` (times [s], values [m/s²] at the sensor's rate): emitted
        as block means of 1/:data:`DISPLAY_RATE` s once a block is complete."""
        with self._lock:
            old_t, old_a = self._carry.get(sensor, (np.empty(0), np.empty(0)))
            t, a = np.concatenate([old_t, t]), np.concatenate([old_a, a])
            if len(t) < 2:
                self._carry[sensor] = (t, a)
                return
            step = float(np.median(np.diff(t)))
            block = max(1, round(1.0 / (DISPLAY_RATE * step))) if step > 0 else 1
            full = len(t) // block * block
            self._carry[sensor] = (t[full:], a[full:])
        if full:
            means_t = t[:full].reshape(-1, block).mean(axis=1)
            means_a = a[:full].reshape(-1, block).mean(axis=1)
            self.put("accel", means_t.tolist(), means_a.tolist())

    def drain(self) -> list[tuple[Any, ...]]:
        """Every item put since the last drain, oldest first."""
        out = []
        while True:
            try:
                out.append(self._items.popleft())
            except IndexError:
                return out


def commanded_fall_line(drive: Any) -> tuple[list[float], list[float]]:
    """The drive's commanded plate-x acceleration (surge acceleration × cos β) at :data:`DISPLAY_RATE`."""
    return block_means(np.asarray(drive.t), np.asarray(drive.accelerations)[:, 0] * math.cos(drive.angle),
                       drive.rate)
