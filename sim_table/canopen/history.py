"""The recent history the endpoint answers SYNCs from: leg lengths and accelerations at the physics' ticks,
kept long enough that a SYNC handled late is answered with the values of its own instant."""

from __future__ import annotations

import math

import numpy as np

HISTORY = 4096
"""Ticks of leg lengths and accelerations kept for the feedback (4.1 s at 1 kHz). A SYNC is answered with the
values of its instant, however late this process handles it, while that instant is kept: with 512 ticks, SYNCs
handled 0.6–1.2 s late (the emulator's process unscheduled that long beside busy processes) were answered with the
oldest kept values instead, a plate 4–17 mm ahead of where it was."""


class Recent:
    """The last ``capacity`` samples (``width`` values each) of a quantity sampled at evenly spaced times [ns]."""

    def __init__(self, width: int, capacity: int = HISTORY) -> None:
        self._times = np.zeros(capacity, dtype=np.int64)
        self._values = np.zeros((capacity, width))
        self._written = 0

    def extend(self, t_start_ns: int, spacing_ns: int, block: np.ndarray) -> None:
        """Append ``block`` (k, width), row j taken at ``t_start_ns + j·spacing_ns``."""
        block = np.asarray(block, dtype=float)[-len(self._times):]
        rows = (self._written + np.arange(len(block))) % len(self._times)
        self._times[rows] = t_start_ns + spacing_ns * np.arange(len(block), dtype=np.int64)
        self._values[rows] = block
        self._written += len(block)

    @property
    def oldest_ns(self) -> int | None:
        """Time of the oldest sample kept [ns] (None before the first)."""
        if not self._written:
            return None
        return int(self._times[self._written % len(self._times)] if self._written > len(self._times)
                   else self._times[0])

    @property
    def newest_ns(self) -> int | None:
        """Time of the newest sample [ns] (None before the first)."""
        return int(self._times[(self._written - 1) % len(self._times)]) if self._written else None

    def at(self, t_ns: int) -> np.ndarray:
        """The values at ``t_ns`` (not after the newest sample), interpolated linearly; the oldest kept before it."""
        capacity = len(self._times)
        newest = (self._written - 1) % capacity
        t_new = int(self._times[newest])
        if self._written == 1:
            return self._values[newest].copy()
        spacing = t_new - int(self._times[(self._written - 2) % capacity])
        back = min(max(t_new - t_ns, 0) / spacing, min(self._written, capacity) - 1)
        whole = math.floor(back)
        late = self._values[(newest - whole) % capacity]
        early = self._values[(newest - whole - 1) % capacity] if whole < back else late
        return late + (early - late) * (back - whole)
