"""Short garbage-collector pauses while a table link is open.

CPython's cyclic collector holds the GIL for a whole pass, in whichever thread's allocation set it off, and a
full pass (generation 2) visits every container object the process holds. Measured on a quiet 2-core machine
(``benchmarks/heap.py``): 11 ms for the 81k objects of ``rig`` with its analysis and emulator imported, 143 ms for
the 274k of this project's test session, several times that with the other core busy. A pass of that length stops
the link's heartbeat and receive threads and the setpoint stream: longer than the controller's 100 ms heartbeat
watchdog and the stream's lead, so the table stops (``HEARTBEAT_LOST``, ``UNDERRUN``) for the host's own
housekeeping.

While a link is open its process's objects sit in the collector's permanent generation (:func:`gc.freeze`): a
full pass then visits only the objects made since, a few milliseconds. Every :class:`HeapHold` that holds keeps
them there; :func:`refreeze` moves what was made since (a stream calls it as it starts: the session's buffers
and analysis of the runs before); when the last hold is released they go back to the oldest generation
(:func:`gc.unfreeze`) and are collected as usual. The cost: a reference cycle that was frozen and became garbage
is freed only after the last release (the collector does not look at it before); cycles made and dropped while
the link is open are collected as usual, and the young generations are collected before each freeze, so only
garbage that already reached the oldest generation waits.
"""

from __future__ import annotations

import gc
import threading

_lock = threading.Lock()
_holds = 0


def refreeze() -> None:
    """Collect the young generations, then move every tracked object to the permanent generation (a few ms: the
    young generations are small; the oldest is not visited)."""
    gc.collect(1)
    gc.freeze()


class HeapHold:
    """One link's share in keeping the heap frozen (module docstring); :meth:`hold` and :meth:`release` are
    idempotent, so ``connect``/``close`` may call them however often they are called."""

    def __init__(self) -> None:
        self._held = False

    @property
    def held(self) -> bool:
        return self._held

    def hold(self) -> None:
        """Freeze the heap (again) and count this holder in, unless it is counted already."""
        global _holds
        with _lock:
            if not self._held:
                self._held = True
                _holds += 1
            refreeze()

    def release(self) -> None:
        """Count this holder out; the last one out unfreezes the heap."""
        global _holds
        with _lock:
            if not self._held:
                return
            self._held = False
            _holds -= 1
            if _holds == 0:
                gc.unfreeze()
