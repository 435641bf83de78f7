"""SYNC timing: where each SYNC of the master's cycle falls on the controller's clock (the *SYNC clock* of
:mod:`sim_table.canopen.endpoint`), as a drive's PLL places it."""

from __future__ import annotations

SERIES_GAP = 0.1
"""A SYNC after this long without one [s, real time] starts a new series (a new master, or one that was stopped)."""

DRIFT = 1e-4
"""How fast the SYNC grid may drift later [s per s]: the master's clock may run slower than the controller's."""


class SyncGrid:
    """Places the SYNCs of a series on the master's cycle: SYNC n at ``φ + n·period`` [ns, controller time]
    (:mod:`sim_table.canopen.endpoint`, *SYNC clock*). ``gap_ns``: a silence that starts a new series;
    ``overflow``: the SYNC counter's overflow value (0x1019; 0: SYNCs carry no counter)."""

    def __init__(self, period_ns: int, gap_ns: int, overflow: int = 0) -> None:
        self.period_ns = period_ns
        self.gap_ns = gap_ns
        self.overflow = overflow
        self._phase = 0
        self._count = -1
        self._last: int | None = None
        self._counter = 0

    def place(self, arrival_ns: int, counter: int = 0) -> tuple[int, bool]:
        """The slot [ns] of a SYNC that arrived at ``arrival_ns`` carrying ``counter`` (1..overflow; 0: none), and
        whether it starts a new series. Without a counter a silence longer than ``gap_ns`` starts one. With it, a
        SYNC whose counter continues the last one's stays in the series however long the silence before it (the
        master was held up, or SYNCs were lost on the way: the count moves on by the counter's step) unless half
        the counter's period passed; one whose counter does not follow (the same counter again, or a step the time
        since the last SYNC cannot hold: a new master counting from 1) starts a new series."""
        step = 1
        if self._last is None:
            new = True
        elif self.overflow and counter and self._counter:
            step = (counter - self._counter) % self.overflow
            since = arrival_ns - self._last  # a step of k means k − 1 SYNCs lost: they take (k − 1) cycles to send
            new = step == 0 or since > self.overflow * self.period_ns // 2 or since < (step - 1) * self.period_ns
        else:
            new = arrival_ns - self._last > self.gap_ns
        self._last, self._counter = arrival_ns, counter
        if new:
            self._count, self._phase = 0, arrival_ns
            return arrival_ns, True
        self._count += step
        drifted = self._phase + round(DRIFT * self.period_ns)
        earliest = self._phase - self.period_ns // 2  # a slot never moves back by half a cycle or more
        self._phase = max(min(drifted, arrival_ns - self._count * self.period_ns), earliest)
        return self._phase + self._count * self.period_ns, False
