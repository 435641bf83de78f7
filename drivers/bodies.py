"""The bodies a table controller reports standing on its plate (``docs/table-controller.md``, Bodies on the plate):
what the host compares with its sequence's bodies before any motion.

The emulator reports its specimens (size and place); a real controller reports a body per overturn-detector
channel, with the size and place it was configured with (zeros when it knows none: then only the number of bodies
can be compared). Transports: MAVLink ``SHAKETABLE_BODY``; zenoh the ``bodies`` queryable; CANopen the overturn
detector's object dictionary, read by SDO (``protocols.canopen.sensors``). A controller that does not report them
(a CANopen detector without the objects) gives None from `TableController.bodies`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class TableBody:
    """One body on the plate as the controller reports it: ``body_id`` (as in overturn events), breadth ``b`` along
    the plate's x (the fall line), height ``h``, ``depth`` along y, and the centre of its base at (``x``, ``y``) on
    the plate, all in metres (zeros: not known to the controller)."""

    body_id: int
    b: float
    h: float
    depth: float
    x: float
    y: float


class BodyReports:
    """The body messages received so far (the receive thread adds them, :meth:`wait` returns the complete set)."""

    def __init__(self) -> None:
        self._bodies: dict[int, TableBody] = {}
        self._count: int | None = None
        self._changed = threading.Condition()

    def add(self, count: int, body: TableBody | None) -> None:
        """A report: ``count`` bodies on the plate, ``body`` one of them (None with count 0)."""
        with self._changed:
            if count != self._count:
                self._bodies, self._count = {}, count
            if body is not None and body.body_id < count:
                self._bodies[body.body_id] = body
            self._changed.notify_all()

    def wait(self, timeout: float) -> tuple[TableBody, ...] | None:
        """Every body reported, in id order, once all ``count`` have come (within ``timeout`` [s]); None if not."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while self._count is None or len(self._bodies) < self._count:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(left)
            return tuple(self._bodies[k] for k in sorted(self._bodies))
