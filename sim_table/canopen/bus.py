"""The emulated CANopen bus's plumbing: python-can's ``virtual`` bus passing frames' time stamps on, and the
COB-IDs the endpoint listens to (:mod:`sim_table.canopen.endpoint`)."""

from __future__ import annotations

import copy
import time

import can
from can.interfaces.virtual import VirtualBus


class StampingVirtualBus(VirtualBus):
    """python-can's ``virtual`` bus passing each frame's own time stamp on (``preserve_timestamps``: the TPDOs carry
    their SYNC's) and stamping a frame sent without one (canopen's heartbeats, boot-ups and SDO answers: time stamp
    0) when it is sent, as a CAN interface stamps a frame when it receives it: the master judges the nodes'
    heartbeats by their time stamps (:meth:`drivers.canopen.faults.FaultSupervision.silent`)."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if not msg.timestamp:  # a copy: canopen's periodic heartbeat task sends the same message again
            msg = copy.copy(msg)
            msg.timestamp = time.time()
        super().send(msg, timeout)


SYNC_COB_ID = 0x80
_NMT_COB_ID = 0x000
_HEARTBEAT_COB_ID = 0x700
