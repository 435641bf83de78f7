"""The leg drives' PDO maps as data: what the master and the emulated drive both configure nodes with.

Directions are the drive's (CiA 301): the drive *receives* RPDO1 and *transmits* TPDO1. Both are synchronous,
transmission type 1: the drive acts on the RPDO1 it last received at the next SYNC, and transmits TPDO1 on
every SYNC. COB-IDs are those of the predefined connection set (RPDO1 0x200 + node id, TPDO1 0x180 + node id);
TPDOs do not answer remote frames (bit 30 of their COB-ID entry set, as CiA 301 recommends).
Payloads are little-endian, objects packed in map order:

========  =====  ==============================================================================
PDO       bytes  content
========  =====  ==============================================================================
RPDO1     6      controlword 0x6040 (UNSIGNED16), target position 0x607A (INTEGER32, increments)
TPDO1     6      statusword 0x6041 (UNSIGNED16), position actual value 0x6064 (INTEGER32, increments)
TPDO1     7      as above, then the answered SYNC's counter 0x2012 (UNSIGNED8): :data:`TPDO1_COUNTED`
========  =====  ==============================================================================

**Answers that say which SYNC they answer.** A master dates a TPDO by the last SYNC it sent before the frame's
receive time stamp: exact for a drive that answers within the cycle, wrong for one that answers later (an emulated
drive on a busy host). With the SYNC counter on (0x1019, CiA 301: each SYNC carries a counter 1..overflow) and
:data:`TPDO1_COUNTED` mapped, every answer carries its SYNC's counter, so the master dates it however late it comes
(up to a counter period). It costs a byte per SYNC and per TPDO (:mod:`protocols.canopen.bus_load`).

Following error actual value 0x60F4 (INTEGER32) is not in TPDO1: with it the PDO would need 10 bytes of
the 8 a CAN frame holds, and a second TPDO per axis costs about 40 % more bus time per cycle
(:mod:`protocols.canopen.bus_load`). The drive watches the following error itself against the window 0x6065
and reports it in statusword bit 13 (and with EMCY 0x8611); 0x60F4 stays readable by SDO.
"""

from __future__ import annotations

import numbers
import struct
from dataclasses import dataclass, field
from typing import Generic, NamedTuple, TypeVar

import canopen

from protocols.canopen import od


class PdoError(ValueError):
    """A PDO payload or value that does not fit its map."""


@dataclass(frozen=True)
class MappedObject:
    """One object in a PDO map: index, sub-index, size [bits] and whether it is a signed integer."""

    index: int
    subindex: int
    bits: int
    signed: bool

    @property
    def mapping_entry(self) -> int:
        """The 0x16xx/0x1Axx entry (UNSIGNED32): index << 16 | sub-index << 8 | bits."""
        return self.index << 16 | self.subindex << 8 | self.bits


class Setpoint(NamedTuple):
    """RPDO1: controlword (0x6040) and target position (0x607A) [increments]."""

    controlword: int
    target_position: int


class Feedback(NamedTuple):
    """TPDO1: statusword (0x6041) and position actual value (0x6064) [increments]."""

    statusword: int
    position_actual: int


class CountedFeedback(NamedTuple):
    """TPDO1_COUNTED: statusword (0x6041), position actual value (0x6064) [increments] and the counter of the SYNC
    it answers (0x2012; 0 when that SYNC carried none)."""

    statusword: int
    position_actual: int
    sync_counter: int


R = TypeVar("R", bound=NamedTuple)  # the NamedTuple a PDO decodes to

_FORMATS = {(8, False): "B", (8, True): "b", (16, False): "H", (16, True): "h", (32, False): "I", (32, True): "i"}


@dataclass(frozen=True)
class PdoSpec(Generic[R]):
    """A PDO of the drive: its number, direction, mapped objects and transmission type.

    ``record`` is the named tuple :meth:`decode` returns (one field per mapped object, in map order).
    """

    name: str
    receive: bool
    number: int
    objects: tuple[MappedObject, ...]
    record: type[R]
    transmission_type: int = 1
    _struct: struct.Struct = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not 1 <= self.number <= 4:
            raise PdoError(f"{self.name}: PDO number {self.number} is outside the predefined connection set 1..4")
        if len(self.objects) != len(self.record._fields):
            raise PdoError(f"{self.name}: {len(self.objects)} objects for the {len(self.record._fields)} fields "
                           f"of {self.record.__name__}")
        if any((obj.bits, obj.signed) not in _FORMATS for obj in self.objects):
            raise PdoError(f"{self.name}: mapped objects must be 8, 16 or 32-bit integers")
        formats = [_FORMATS[obj.bits, obj.signed] for obj in self.objects]
        if sum(obj.bits for obj in self.objects) > 64:
            raise PdoError(f"{self.name}: {sum(obj.bits for obj in self.objects)} bits do not fit the 64 of a frame")
        object.__setattr__(self, "_struct", struct.Struct("<" + "".join(formats)))

    @property
    def communication_index(self) -> int:
        """Index of the communication parameter record (0x1400.. RPDO, 0x1800.. TPDO)."""
        return (0x1400 if self.receive else 0x1800) + self.number - 1

    @property
    def mapping_index(self) -> int:
        """Index of the mapping parameter record (0x1600.. RPDO, 0x1A00.. TPDO)."""
        return (0x1600 if self.receive else 0x1A00) + self.number - 1

    @property
    def size(self) -> int:
        """Payload length [bytes]."""
        return self._struct.size

    def cob_id(self, node_id: int) -> int:
        """The PDO's COB-ID on node ``node_id`` (predefined connection set)."""
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
            raise PdoError(f"CANopen node id must be an integer in 1..127, got {node_id!r}")
        return (0x200 if self.receive else 0x180) + 0x100 * (self.number - 1) + node_id

    def cob_id_entry(self, node_id: int) -> int:
        """Sub 1 of the communication record of the enabled PDO: the COB-ID, with bit 30 (no RTR) on a TPDO."""
        return self.cob_id(node_id) | (0 if self.receive else 1 << 30)

    def encode(self, values: R) -> bytes:
        """The payload carrying ``values`` (one integer per mapped object, in map order)."""
        if len(values) != len(self.objects):
            raise PdoError(f"{self.name} carries {len(self.objects)} values, got {len(values)}")
        for name, obj, value in zip(self.record._fields, self.objects, values, strict=True):
            low, high = (-(1 << (obj.bits - 1)), (1 << (obj.bits - 1)) - 1) if obj.signed else (0, (1 << obj.bits) - 1)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= int(value) <= high:
                raise PdoError(f"{self.name}: {name} must be an integer in {low}..{high}, got {value!r}")
        return self._struct.pack(*(int(value) for value in values))

    def decode(self, data: bytes) -> R:
        """The values a payload carries; :class:`PdoError` unless it has exactly :attr:`size` bytes."""
        if len(data) != self.size:
            raise PdoError(f"{self.name} payload is {len(data)} bytes, expected {self.size}")
        return self.record._make(self._struct.unpack(data))


RPDO1: PdoSpec[Setpoint] = PdoSpec(
    "RPDO1", receive=True, number=1, record=Setpoint,
    objects=(MappedObject(od.CONTROLWORD, 0, 16, False), MappedObject(od.TARGET_POSITION, 0, 32, True)))
"""Master → drive on every cycle: controlword and target position."""

TPDO1: PdoSpec[Feedback] = PdoSpec(
    "TPDO1", receive=False, number=1, record=Feedback,
    objects=(MappedObject(od.STATUSWORD, 0, 16, False), MappedObject(od.POSITION_ACTUAL_VALUE, 0, 32, True)))
"""Drive → master on every SYNC: statusword and position actual value."""

TPDO1_COUNTED: PdoSpec[CountedFeedback] = PdoSpec(
    "TPDO1", receive=False, number=1, record=CountedFeedback,
    objects=(*TPDO1.objects, MappedObject(od.ANSWERED_SYNC, 0, 8, False)))
"""Drive → master on every SYNC: statusword, position actual value and the answered SYNC's counter."""

PDO_MAPS: tuple[PdoSpec, ...] = (RPDO1, TPDO1)
"""The leg drives' PDO maps as their EDS defaults (a master that dates answers by counter maps
:data:`TPDO1_COUNTED` in TPDO1's place)."""


def configure(pdo_map: canopen.pdo.PdoMap, spec: PdoSpec, node_id: int) -> None:
    """Set a ``canopen`` PDO map (of a ``RemoteNode`` or a ``LocalNode``) to ``spec`` for node ``node_id``.

    Changes the map object only; ``pdo_map.save()`` then writes it to the node by SDO (and subscribes the
    PDO on the network), ``pdo_map.read()`` reads back what the node holds.
    """
    index = pdo_map.map_array.od.index
    if index != spec.mapping_index:
        raise PdoError(f"{spec.name} is mapped at 0x{spec.mapping_index:04X}, not at this map's 0x{index:04X}")
    pdo_map.clear()
    for obj in spec.objects:
        pdo_map.add_variable(obj.index, obj.subindex, obj.bits)
    pdo_map.cob_id = spec.cob_id(node_id)
    pdo_map.trans_type = spec.transmission_type
    pdo_map.rtr_allowed = spec.receive  # canopen sets bit 30 when not allowed; an RPDO has no RTR to refuse
    pdo_map.enabled = True
