"""The CANopen master's clock: what paces its SYNC cycle and dates what it stamps (package docstring, *Time*).

The master reads time through :class:`Clock` — ``now_ns()`` and ``sleep_until(ns)``, as python-can's buses and
scipy's solvers take the few calls they need as an interface. :class:`WallClock` (host monotonic time, the default)
is the only one for a real bus. :class:`SteppedClock` is virtual time for drives emulated in the same process: the
cycle's every sleep first lets the emulated drives settle (a hook the test gives: every frame sent so far handled),
then jumps to the deadline, so the drives run in lockstep with the master and a test takes the time the frames take
to handle, not the table time it plays. The waits of the caller's commands keep their timeouts in real seconds: they
guard against silence (an SDO that is not answered, a cycle that stopped), they pace nothing.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol

from drivers.controller import sleep_until


class Clock(Protocol):
    """Monotonic time [ns] and sleeping to an absolute deadline on it."""

    def now_ns(self) -> int:
        """The time now [ns]; never decreases."""
        ...

    def sleep_until(self, deadline_ns: int) -> int:
        """Return once the time is ``deadline_ns`` [ns] or later; how late the return is [ns, ≥ 0 unless the
        clock is the wall clock and the deadline had passed: then how late the call was]."""
        ...


class WallClock:
    """Host monotonic time (``time.monotonic_ns``): the clock of a real bus."""

    def now_ns(self) -> int:
        return time.monotonic_ns()

    def sleep_until(self, deadline_ns: int) -> int:
        return sleep_until(deadline_ns)


class SteppedClock:
    """Virtual time (module docstring) that starts at ``start_ns`` and moves only when advanced: by
    :meth:`advance_to`, or by a sleeper, which first calls ``settle`` (the emulated drives handle everything sent
    to them so far; None: nothing to wait for) and then sets the time to its deadline. Thread-safe."""

    def __init__(self, settle: Callable[[], None] | None = None, start_ns: int = 1_000_000_000) -> None:
        if start_ns < 0:
            raise ValueError(f"start_ns must be >= 0, got {start_ns}")
        self._settle = settle
        self._now = start_ns
        self._lock = threading.Lock()

    def now_ns(self) -> int:
        with self._lock:
            return self._now

    def advance_to(self, t_ns: int) -> None:
        """Move the time to ``t_ns`` [ns] (never back: an earlier time leaves it where it is)."""
        with self._lock:
            self._now = max(self._now, t_ns)

    def sleep_until(self, deadline_ns: int) -> int:
        """Settle the emulated drives, then jump to ``deadline_ns``; how far past it the time is [ns] (0 unless
        :meth:`advance_to` went beyond it)."""
        if self._settle is not None:
            self._settle()
        with self._lock:
            self._now = max(self._now, deadline_ns)
            return self._now - deadline_ns
