"""What the CANopen master knows of each node on the bus: its heartbeat and NMT state, its EMCYs, and per kind
(leg drive, accelerometer) what its PDOs last reported."""

from __future__ import annotations

import time

import canopen

from drivers.canopen.clock import Clock
from protocols.canopen import LegScaling, State, decode_statusword

NMT_OPERATIONAL = 0x05
"""The NMT state a heartbeat reports for *operational*."""


class NodeLink:
    """What the master knows of one node: its ``RemoteNode``, last heartbeat (when handled [ns, the master's
    ``clock``] and the frame's
    time stamp [s, the bus's clock: ``time.time()`` at reception]), the NMT state that heartbeat reported, and EMCYs."""

    def __init__(self, node: canopen.RemoteNode, clock: Clock) -> None:
        if node.id is None:
            raise ValueError("a node of the master's network needs a node-ID; this one has none")
        self.node = node
        self.node_id: int = node.id
        """The node's id (1..127)."""
        self.clock = clock
        self.heartbeat_ns: int | None = None
        self.heartbeat_stamp = 0.0
        self.nmt_state: int | None = None
        self.started_ns = 0  # when the master last sent it the NMT start command [ns, the clock]
        self.emcy: list[tuple[int, int]] = []  # (code, ns of the clock)
        node.nmt.add_heartbeat_callback(self._beat)

    def _beat(self, state: int) -> None:
        self.heartbeat_ns = self.clock.now_ns()
        stamp = self.node.nmt.timestamp  # the frame's, set by canopen before it calls back
        self.heartbeat_stamp = time.time() if stamp is None else stamp
        self.nmt_state = state

    def heartbeat_age(self, now: int) -> float | None:
        """Seconds since its last heartbeat (None before the first)."""
        return None if self.heartbeat_ns is None else (now - self.heartbeat_ns) * 1e-9


class DriveLink(NodeLink):
    """A leg drive: its leg's scaling (metres ↔ the drive's units, established at connect), its last statusword and
    position [drive units], the controlword last sent."""

    def __init__(self, node: canopen.RemoteNode, clock: Clock, scaling: LegScaling) -> None:
        super().__init__(node, clock)
        self.scaling = scaling
        self.statusword: int | None = None
        self.position = 0
        self.answered = -1  # the SYNC whose answer gave statusword and position
        self.word = 0

    @property
    def state(self) -> State | None:
        return None if self.statusword is None else decode_statusword(self.statusword)


class SensorLink(NodeLink):
    """An accelerometer: the samples waiting to be published as one batch."""

    def __init__(self, node: canopen.RemoteNode, clock: Clock, sensor_id: int) -> None:
        super().__init__(node, clock)
        self.sensor_id = sensor_id
        self.pending: list[tuple[int, tuple[float, float, float]]] = []  # (SYNC index, force)
        self.next_index: int | None = None
        self.seq = 0
        self.lost = 0
        self.stale = 0  # samples dropped: their SYNC's index was had, or counted lost, already
