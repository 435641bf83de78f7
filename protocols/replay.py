"""Replay protection of signed streams, after MAVLink 2's timestamp rules, for both signed transports.

A signed message carries its sender's stream (MAVLink: link id, system, component; zenoh: sender id and key
expression) and a stamp that rises along the stream (MAVLink: 10 µs units since 2015-01-01 UTC; zenoh: µs since
1970-01-01 UTC). A receiver keeps a :class:`ReplayGuard` and takes a correctly signed message only when
:meth:`ReplayGuard.check` finds its stamp fresh. The rules (MAVLink's "Timestamp Handling", with its one minute
narrowed to ``window`` and a bound on the future added):

- the receiver's **current stamp** is the largest of its wall clock, the stamp it restored at start (a controller
  keeps its guard's :class:`ReplayState` in a file, ``sim_table.replay_store``) and the largest stamp it has taken
  since: a clock that jumps back, or a controller that restarts with its clock behind, cannot make it forget what
  it has heard;
- a stream it knows: the stamp must be above the stream's last one (replayed and reordered messages are refused);
- a stream it does not know: the stamp may be at most ``window`` behind the current stamp;
- any stamp more than ``ahead`` beyond the current stamp is refused (FUTURE): a sender whose clock runs ahead, or a
  message made for a receiver whose clock was behind, opens nothing; and one accepted stamp far in the future would
  otherwise refuse every later stream that is on time.

Only a message whose signature verified moves the guard (:meth:`ReplayGuard.accept`): a forged stamp moves nothing.
"""

from __future__ import annotations

import enum
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import NamedTuple

REMEMBERED_STREAMS = 1024
"""Streams whose last stamp a :class:`ReplayGuard` keeps (the least recently heard is forgotten first)."""


class Freshness(enum.Enum):
    """What :meth:`ReplayGuard.check` found for a stamp."""

    FRESH = "fresh"
    STALE = "stale"  # not above its stream's last stamp, or a new stream too far behind the current stamp
    FUTURE = "future"  # too far ahead of the current stamp


class ReplayState(NamedTuple):
    """What a guard must keep across a restart: the ``current`` stamp and each stream's last stamp, least recently
    heard first."""

    current: int
    streams: tuple[tuple[Hashable, int], ...]


class ReplayGuard:
    """The freshness rules of the module docstring for one receiver.

    ``clock()`` the wall clock in stamp units; ``window`` how far behind the current stamp a new stream may open,
    ``ahead`` how far beyond it any stamp may be [stamp units]; ``state`` restored from a previous run. Thread-safe.
    """

    def __init__(self, clock: Callable[[], int], window: int, ahead: int, *, state: ReplayState | None = None,
                 remembered: int = REMEMBERED_STREAMS) -> None:
        if window < 0 or ahead < 0 or remembered < 1:
            raise ValueError(f"window and ahead must be >= 0 and remembered >= 1, got {window}, {ahead}, {remembered}")
        self._clock = clock
        self.window, self.ahead, self.remembered = window, ahead, remembered
        self._lock = threading.Lock()
        self._highest = state.current if state is not None else 0
        self._last: OrderedDict[Hashable, int] = OrderedDict(state.streams if state is not None else ())
        while len(self._last) > remembered:
            self._last.popitem(last=False)
        self.changes = 0
        """Stamps accepted so far (a keeper of the state saves it when this moved)."""

    def current(self) -> int:
        """The current stamp: the largest of the wall clock, the restored stamp and every stamp accepted."""
        return max(self._clock(), self._highest)

    def check(self, stream: Hashable, stamp: int) -> Freshness:
        """Whether ``stamp`` on ``stream`` is fresh (module docstring); moves nothing."""
        with self._lock:
            now = self.current()
            if stamp > now + self.ahead:
                return Freshness.FUTURE
            last = self._last.get(stream)
            if last is not None:
                return Freshness.FRESH if stamp > last else Freshness.STALE
            return Freshness.FRESH if stamp >= now - self.window else Freshness.STALE

    def accept(self, stream: Hashable, stamp: int) -> None:
        """Record ``stamp`` as ``stream``'s last: call it for a message whose signature verified and that
        :meth:`check` found fresh."""
        with self._lock:
            self._last[stream] = max(stamp, self._last.get(stream, stamp))
            self._last.move_to_end(stream)
            if len(self._last) > self.remembered:
                self._last.popitem(last=False)
            self._highest = max(self._highest, stamp)
            self.changes += 1

    def admit(self, stream: Hashable, stamp: int) -> Freshness:
        """:meth:`check`, and :meth:`accept` when fresh: for a message whose signature already verified."""
        freshness = self.check(stream, stamp)
        if freshness is Freshness.FRESH:
            self.accept(stream, stamp)
        return freshness

    def knows(self, stream: Hashable) -> bool:
        """Whether ``stream`` has a last stamp here."""
        with self._lock:
            return stream in self._last

    def state(self) -> ReplayState:
        """A copy of what must survive a restart."""
        with self._lock:
            return ReplayState(self._highest, tuple(self._last.items()))
