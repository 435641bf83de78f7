"""The emulated CANopen nodes (:mod:`protocols.canopen`): the CiA 402 leg drives, the plate accelerometers and the
overturn detector, each a ``canopen.LocalNode`` with the values it computes, and what the drives declare (target
and feedback delays, 0x2010 and 0x2011). The endpoint (:mod:`sim_table.canopen.endpoint`) drives them."""

from __future__ import annotations

from typing import Any

import canopen

from protocols.canopen import (
    RPDO1,
    TPDO1,
    TPDO1_COUNTED,
    PdoSpec,
    State,
    StatusBit,
    statusword,
)
from protocols.canopen import od as drive_od
from protocols.canopen.sensors import (
    ACCEL_TPDO1,
    ACCEL_TPDO1_COUNTED,
    BODY_COUNT,
    BODY_RECORDS,
    EVENT_TPDO1,
    MAX_BODIES,
    OVERTURN_EVENT,
    SAMPLE_DELAY,
    SPECIFIC_FORCE,
    ForceSample,
    event_record,
)
from sim_table.canopen.history import Recent
from sim_table.endpoint import BodyOnPlate

TARGET_DELAY = 0.060
"""What the emulated drives declare in 0x2010 [s] unless the listen URL sets ``target_delay``: a target is reached
this long after the SYNC that latched it."""

TARGET_DELAY_RANGE = (0.010, 2.0)
"""The target delays [s] the emulated drives can be set to (``target_delay`` in the listen URL)."""

FEEDBACK_DELAY = 0.015
"""What the emulated drives declare in 0x2011 and the accelerometers in 0x2101 [s]: the position actual value and
the acceleration sample of a SYNC's TPDO are this much older than the SYNC. Longer than the emulator's wake period
(``sim_table.process.CANOPEN_WAKE_PERIOD_NS``, 10 ms), so the physics has computed that instant when the SYNC comes
and the answer leaves at once: measured with ``udp_multicast`` at 100 Hz on an idle machine (the two-process
test, about 330 SYNCs), 4 ms deferred 181–335 answers to the next batch and the master lost 4–61 accelerometer
samples (an answer after the next SYNC is taken for that one's), 15 ms deferred 0–2 and lost 0–1. An answer still
waits for a late batch (counted: ``feedback_deferred``)."""


_WINDOW_OFF = 0xFFFF_FFFF
"""0x6065 value that switches the following-error supervision off (CiA 402)."""
_COUNTED = (TPDO1_COUNTED, ACCEL_TPDO1_COUNTED)


class _Node:
    """One emulated node: its ``LocalNode``, the PDO maps it supports (``receives``: the spec of its RPDO1;
    ``transmit_maps``: those its TPDO1 may hold, the master chooses), the one the master mapped in TPDO1
    (``transmits``), and whether it read the maps the master wrote since NMT last changed its state."""

    receives: PdoSpec | None = None
    transmit_maps: tuple[PdoSpec, ...] = ()

    def __init__(self, node: canopen.LocalNode) -> None:
        self.node = node
        self.mapped = False
        self.supported = False
        self.transmits: PdoSpec | None = None
        node.add_read_callback(self._read)

    def _read(self, index: int, subindex: int, od: Any) -> float | None:
        """The live value of an object the device computes (None: the object dictionary's)."""
        return None

    def written(self, index: int) -> int:
        """The integer object ``index`` (sub 0) holds: as the master wrote it, else the EDS default."""
        entry = self.node.object_dictionary[index]
        if not isinstance(entry, canopen.objectdictionary.ODVariable):
            raise TypeError(f"0x{index:04X} of node {self.node.id} is a record or an array, not one value")
        return int(entry.decode_raw(self.node.get_data(index, 0)))

    @property
    def operational(self) -> bool:
        return self.node.nmt.state == "OPERATIONAL"

    def pdos(self) -> bool:
        """Whether the node's PDOs work: operational, and the maps the master wrote (read on the first call since
        NMT started it) are ones the device supports (its PDO specs; another map gets no PDO traffic)."""
        if not self.operational:
            return False
        if not self.mapped:
            self.node.pdo.read()
            self.mapped = True
            rpdo, tpdo = _first_map(self.node.rpdo), _first_map(self.node.tpdo)
            self.transmits = next((spec for spec in self.transmit_maps if _maps(tpdo, spec)), None)
            self.supported = (self.receives is None or _maps(rpdo, self.receives)) and (
                not self.transmit_maps or self.transmits is not None)
        return self.supported

    def counted(self) -> bool:
        """Whether the TPDO1 the master mapped carries the answered SYNC's counter (last object, UNSIGNED8)."""
        return self.transmits in _COUNTED


def _first_map(pdos: canopen.pdo.PdoBase) -> canopen.pdo.PdoMap | None:
    """PDO 1 of a node's RPDOs or TPDOs (None: its object dictionary has none)."""
    return None if pdos.map is None else pdos.map.get(1)


def _maps(pdo_map: Any, spec: PdoSpec) -> bool:
    """Whether a ``canopen`` PDO map holds exactly ``spec``'s objects (or is disabled)."""
    return not pdo_map.enabled or [(v.index, v.subindex, v.length) for v in pdo_map.map] == [
        (o.index, o.subindex, o.bits) for o in spec.objects]


class _Drive(_Node):
    """One emulated leg drive: CiA 402 state, latched setpoint, the position it reports."""

    receives, transmit_maps = RPDO1, (TPDO1, TPDO1_COUNTED)

    def __init__(self, node: canopen.LocalNode, target_delay: float) -> None:
        super().__init__(node)
        self.target_delay = target_delay
        self.state = State.SWITCH_ON_DISABLED
        self.previous_word = 0
        self.target = 0
        self.position = 0
        self.following_error = 0
        """0x60F4 [µm]: commanded − actual leg length at the last SYNC answered."""
        self.following_error_latched = False
        """Statusword bit 13: the following error passed the window (until a fault reset)."""
        self.flags = int(StatusBit.REMOTE)
        self._window: int | None = None
        self._window_read = False  # 0x6065 read since the master last wrote it
        node.add_write_callback(self._written)

    def _written(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        if index == drive_od.FOLLOWING_ERROR_WINDOW:
            self._window_read = False  # the value is stored after the callbacks: read it when next needed

    def _read(self, index: int, subindex: int, od: Any) -> int | None:
        if index == drive_od.STATUSWORD:
            return statusword(self.state, self.flags)
        if index == drive_od.POSITION_ACTUAL_VALUE:
            return self.position
        if index == drive_od.FOLLOWING_ERROR_ACTUAL_VALUE:
            return self.following_error
        if index == drive_od.MODES_OF_OPERATION_DISPLAY:
            return self.mode
        if index == drive_od.TARGET_DELAY:
            return round(self.target_delay * 1e6)
        if index == drive_od.FEEDBACK_DELAY:
            return round(FEEDBACK_DELAY * 1e6)
        return None

    @property
    def mode(self) -> int:
        """Modes of operation 0x6060 as the master set it."""
        return self.written(drive_od.MODES_OF_OPERATION)

    @property
    def following_error_window(self) -> int | None:
        """Following error window 0x6065 [µm] as the master set it (else the EDS default); None when off."""
        if not self._window_read:
            window = self.written(drive_od.FOLLOWING_ERROR_WINDOW)
            self._window, self._window_read = (None if window == _WINDOW_OFF else window), True
        return self._window


class _Sensor(_Node):
    """One emulated plate accelerometer: the samples of its sensor and the one it sends."""

    transmit_maps = (ACCEL_TPDO1, ACCEL_TPDO1_COUNTED)

    def __init__(self, node: canopen.LocalNode) -> None:
        super().__init__(node)
        self.samples = Recent(3)
        self.sample = ForceSample(0, 0, 0)

    def _read(self, index: int, subindex: int, od: Any) -> int | None:
        if index == SPECIFIC_FORCE and 1 <= subindex <= 3:
            return self.sample[subindex - 1]
        if index == SAMPLE_DELAY:
            return round(FEEDBACK_DELAY * 1e6)
        return None


class _Detector(_Node):
    """The emulated overturn detector: the event it is sending and the bodies on the plate it holds."""

    transmit_maps = (EVENT_TPDO1,)

    def __init__(self, node: canopen.LocalNode, bodies: tuple[BodyOnPlate, ...]) -> None:
        super().__init__(node)
        if len(bodies) > MAX_BODIES:
            raise ValueError(f"the CANopen overturn detector holds at most {MAX_BODIES} bodies, got {len(bodies)}")
        self.record = event_record(0, 0, 1, 0.0, 0)
        self.bodies = bodies

    def _read(self, index: int, subindex: int, od: Any) -> float | None:
        if index == OVERTURN_EVENT and 1 <= subindex <= 5:
            return self.record[subindex - 1]
        if index == BODY_COUNT:
            return len(self.bodies)
        k = index - BODY_RECORDS
        if 0 <= k < MAX_BODIES and 1 <= subindex <= 5:
            return self.bodies[k][subindex - 1] if k < len(self.bodies) else 0.0
        return None
