"""The master's SDO requests at connect, typed by the standard rather than by an EDS, and every failure as one line.

A real drive's object dictionary is its vendor's: an object the master uses may be absent, of another size, read
only, or out of range. :class:`NodeSdo` reads and writes objects with the data type CiA 301/402 gives them
(:class:`Kind`), tells an absent object (abort 0x06020000 or 0x06090011: :meth:`NodeSdo.probe` returns None) from a
refusal, and turns every abort, wrong-size answer or silence into a :class:`~drivers.controller.TableError` naming
the node, the object and sub-index, the abort code and its meaning, and what to do (:class:`DriveSetupError`;
silence: :class:`~drivers.controller.TableTimeoutError`). PDO maps are written the same way (:meth:`NodeSdo.map_pdo`),
so a drive that cannot map an object says which.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import canopen
from canopen.sdo.exceptions import SdoError

from drivers.controller import TableError, TableTimeoutError
from protocols.canopen import PdoSpec

ABSENT = frozenset({0x0602_0000, 0x0609_0011})
"""Abort codes of an object (or sub-index) the node does not have."""

_ADVICE = {
    0x0602_0000: "the drive has no such object (docs/table-controller.md, Real drives: what a drive must have)",
    0x0609_0011: "the drive has no such sub-index (docs/table-controller.md, Real drives)",
    0x0601_0002: "the drive has it read only: set it with the vendor's tool, or describe the drive's profile",
    0x0604_0041: "the drive cannot map this object into a PDO: it cannot be driven in CSP by this master",
    0x0604_0042: "the PDO is longer than the drive allows",
    0x0609_0030: "the value is outside the drive's range: check the [drives] table of the rig configuration",
    0x0609_0031: "the value is above the drive's range: check the [drives] table of the rig configuration",
    0x0609_0032: "the value is below the drive's range: check the [drives] table of the rig configuration",
    0x0800_0022: "the drive refuses it in its present state: power it off and on, then connect again",
}


class Kind(NamedTuple):
    """A CiA 301 data type: its name and ``struct`` format (little-endian)."""

    name: str
    fmt: str

    @property
    def size(self) -> int:
        return struct.calcsize(self.fmt)


U8, U16, U32 = Kind("UNSIGNED8", "<B"), Kind("UNSIGNED16", "<H"), Kind("UNSIGNED32", "<I")
I8, I32 = Kind("INTEGER8", "<b"), Kind("INTEGER32", "<i")


class DriveSetupError(TableError):
    """A node refused its set-up, answered what the master cannot use, or is not a drive the master can drive."""


def abort_meaning(code: int) -> str:
    """The standard's words for an SDO abort code (CiA 301)."""
    return canopen.SdoAbortedError.CODES.get(code, "unknown abort code")


class NodeSdo:
    """Typed SDO access to one node (``what`` names it in messages, e.g. "leg 3 (node 3)") of the table at ``url``;
    each request waits ``timeout`` [s]."""

    def __init__(self, url: str, node: canopen.RemoteNode, what: str, timeout: float) -> None:
        if node.id is None:
            raise ValueError(f"{url}: {what} has no node-ID")
        self.url, self.node, self.what = url, node, what
        self.node_id: int = node.id
        node.sdo.RESPONSE_TIMEOUT = timeout

    def where(self, index: int, subindex: int, name: str) -> str:
        return f"{self.url}: {self.what}, 0x{index:04X} sub {subindex} ({name})"

    def _failed(self, index: int, subindex: int, name: str, action: str, exc: Exception) -> TableError:
        where = self.where(index, subindex, name)
        if isinstance(exc, canopen.SdoAbortedError):
            advice = _ADVICE.get(exc.code, "see the drive's manual for this abort code")
            return DriveSetupError(f"{where}: {action} refused with SDO abort 0x{exc.code:08X} "
                                   f"({abort_meaning(exc.code)}): {advice}")
        if isinstance(exc, canopen.SdoCommunicationError):
            return TableTimeoutError(f"{where}: no answer to the SDO {action} within "
                                     f"{self.node.sdo.RESPONSE_TIMEOUT} s ({exc}): is the node powered, on the bus "
                                     "and at this bitrate?")
        return DriveSetupError(f"{where}: {action} failed: {exc}")

    def probe(self, index: int, subindex: int, kind: Kind, name: str) -> int | None:
        """The object's value, None when the node does not have it (an absent object is not an error here)."""
        try:
            data = self.node.sdo.upload(index, subindex)
        except canopen.SdoAbortedError as exc:
            if exc.code in ABSENT:
                return None
            raise self._failed(index, subindex, name, "read", exc) from None
        except SdoError as exc:
            raise self._failed(index, subindex, name, "read", exc) from None
        if len(data) != kind.size:
            raise DriveSetupError(f"{self.where(index, subindex, name)}: the node answered {len(data)} bytes where "
                                  f"CiA 301/402 have a {kind.name} ({kind.size} bytes): a vendor object of another "
                                  "meaning under a standard number? Describe the drive's profile "
                                  "(docs/table-controller.md, Real drives)")
        return struct.unpack(kind.fmt, data)[0]

    def read(self, index: int, subindex: int, kind: Kind, name: str) -> int:
        """The object's value; an absent object is a :class:`DriveSetupError` (the master needs it)."""
        value = self.probe(index, subindex, kind, name)
        if value is None:
            raise DriveSetupError(f"{self.where(index, subindex, name)}: the node does not have it (SDO abort "
                                  f"0x06020000, {abort_meaning(0x0602_0000)}): {_ADVICE[0x0602_0000]}")
        return value

    def write(self, index: int, subindex: int, kind: Kind, value: int, name: str) -> None:
        """Write ``value`` (a :class:`ValueError` for a value the type cannot hold is the caller's bug)."""
        data = struct.pack(kind.fmt, value)
        try:
            self.node.sdo.download(index, subindex, data)
        except SdoError as exc:
            raise self._failed(index, subindex, name, f"write of {value}", exc) from None

    def map_pdo(self, spec: PdoSpec) -> None:
        """Map ``spec`` into the node's PDO (CiA 301's order: the PDO disabled, its map emptied, the objects, their
        count, the transmission type, the PDO enabled again)."""
        comm, mapping = spec.communication_index, spec.mapping_index
        cob_id = spec.cob_id_entry(self.node_id)
        self.write(comm, 1, U32, cob_id | 1 << 31, f"{spec.name} COB-ID, disabled")
        self.write(mapping, 0, U8, 0, f"{spec.name} map: no objects")
        for sub, obj in enumerate(spec.objects, start=1):
            self.write(mapping, sub, U32, obj.mapping_entry, f"{spec.name} map: object 0x{obj.index:04X}")
        self.write(mapping, 0, U8, len(spec.objects), f"{spec.name} map: {len(spec.objects)} objects")
        self.write(comm, 2, U8, spec.transmission_type, f"{spec.name} transmission type")
        self.write(comm, 1, U32, cob_id, f"{spec.name} COB-ID, enabled")
