"""The controller's clock seen from the host: controller time from request/answer round trips.

Every transport asks the controller for its time (MAVLink: TIMESYNC; zenoh: a clock query) and feeds each
round trip to :class:`ClockSync`: request sent at host time ``t_send``, answer carrying controller time ``tc``
received at ``t_recv`` (host monotonic ns). Of the last :data:`CLOCK_WINDOW` round trips, those within 100 µs of
twice the shortest delay are fitted with a line (controller time against the midpoint of send and receive)
through the shortest round trip: offset ``tc − (t_send + t_recv)/2`` there, and the slope follows a controller
clock that runs at another rate (an emulator's ``--speed``, a drifting oscillator) once the round trips span
:data:`FIT_SPAN`.
"""

from __future__ import annotations

import threading
import time
from collections import deque

import numpy as np

CLOCK_WINDOW = 32
"""Round trips kept for the clock estimate."""

FIT_SPAN = 0.2
"""Round trips must span this long [s] before the clock's rate is fitted."""


class ClockSync:
    """Maps host monotonic time to controller time from round trips (module docstring). Thread-safe."""

    def __init__(self, window: int = CLOCK_WINDOW) -> None:
        self._lock = threading.Lock()
        self._samples: deque[tuple[int, int, int]] = deque(maxlen=window)  # (midpoint, tc, round trip) [ns]
        self._anchor = (0, 0)  # (host ns, controller ns) on the line
        self._rate = 1.0
        self.fitted = False
        """Whether the rate comes from a fit (else it is taken as 1)."""
        self.round_trips: list[int] = []
        """Every round trip seen [ns] (for statistics)."""

    def add(self, t_send: int, t_recv: int, tc: int) -> None:
        """One round trip: request sent at host ``t_send``, answer with controller time ``tc`` received at
        ``t_recv`` [ns]."""
        rtt = t_recv - t_send
        if rtt < 0:
            return
        with self._lock:
            self.round_trips.append(rtt)
            self._samples.append(((t_send + t_recv) // 2, tc, rtt))
            best = min(self._samples, key=lambda s: s[2])
            good = [s for s in self._samples if s[2] <= 2 * best[2] + 100_000]
            mids = np.array([s[0] for s in good], dtype=np.float64)
            if len(good) >= 3 and mids.max() - mids.min() >= FIT_SPAN * 1e9:
                tcs = np.array([s[1] for s in good], dtype=np.float64)
                rate, _ = np.polyfit(mids - best[0], tcs - best[1], 1)
                self._rate = float(rate)
                self.fitted = True
            self._anchor = (best[0], best[1])

    def to_controller(self, host_ns: int) -> int:
        """Controller time [ns] at host monotonic time ``host_ns``."""
        with self._lock:
            h, c = self._anchor
            return c + round((host_ns - h) * self._rate)

    def to_host(self, controller_ns: int) -> int:
        """Host monotonic time [ns] at controller time ``controller_ns``."""
        with self._lock:
            h, c = self._anchor
            return h + round((controller_ns - c) / self._rate)

    def stats(self) -> dict[str, float]:
        """Offset [s] (controller − host now), rate, round trips (count, min, median [s])."""
        now = time.monotonic_ns()
        rtts = np.array(self.round_trips or [0], dtype=np.float64) * 1e-9
        return {"offset_s": (self.to_controller(now) - now) * 1e-9, "rate": self._rate,
                "round_trips": len(self.round_trips), "rtt_min_s": float(rtts.min()),
                "rtt_median_s": float(np.median(rtts))}
