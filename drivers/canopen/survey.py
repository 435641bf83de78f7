"""What a leg drive is, read without changing anything (the first step of connecting, and all of ``rig table
check``): identity, device type, supported modes, which optional objects it has, its position unit and factors,
how it can be watched and watch the master, and its manufacturer profile.

**Required** (CiA 301 and CiA 402 for a CSP drive): 0x1000 device type (CiA 402: low word 402), 0x1018 identity
(vendor-ID, product code), 0x6502 supported drive modes with cyclic synchronous position (bit 7), and the objects
the master maps and sets: 0x6040 controlword, 0x6041 statusword, 0x6060/0x6061 modes of operation (display),
0x6064 position actual value, 0x607A target position (mapped in RPDO1/TPDO1: a drive that cannot map them says so
when they are written). **Optional**, each read first and used where it exists (:data:`OPTIONAL`); what the master
does without each is in ``docs/table-controller.md`` (*Real drives*).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import canopen

from drivers.canopen.profiles import DriveProfile, profile_of
from drivers.canopen.sdo import I8, I32, U8, U16, U32, DriveSetupError, Kind, NodeSdo
from protocols.canopen import od as drive_od
from protocols.canopen.units import PositionUnit, decode_position_unit

OPTIONAL: dict[tuple[int, int], tuple[Kind, str]] = {
    (drive_od.COMMUNICATION_CYCLE_PERIOD, 0): (U32, "communication cycle period"),
    (drive_od.GUARD_TIME, 0): (U16, "guard time"),
    (drive_od.LIFE_TIME_FACTOR, 0): (U8, "life time factor"),
    (drive_od.CONSUMER_HEARTBEAT_TIME, 1): (U32, "consumer heartbeat time"),
    (drive_od.PRODUCER_HEARTBEAT_TIME, 0): (U16, "producer heartbeat time"),
    (drive_od.SYNC_COUNTER_OVERFLOW, 0): (U8, "SYNC counter overflow value"),
    (drive_od.FOLLOWING_ERROR_WINDOW, 0): (U32, "following error window"),
    (drive_od.SOFTWARE_POSITION_LIMIT, 1): (I32, "min position limit"),
    (drive_od.SOFTWARE_POSITION_LIMIT, 2): (I32, "max position limit"),
    (drive_od.MAX_PROFILE_VELOCITY, 0): (U32, "max profile velocity"),
    (drive_od.SI_UNIT_POSITION, 0): (U32, "SI unit position"),
    (drive_od.POSITION_ENCODER_RESOLUTION, 1): (U32, "encoder increments"),
    (drive_od.POSITION_ENCODER_RESOLUTION, 2): (U32, "motor revolutions"),
    (drive_od.GEAR_RATIO, 1): (U32, "motor shaft revolutions"),
    (drive_od.GEAR_RATIO, 2): (U32, "driving shaft revolutions"),
    (drive_od.FEED_CONSTANT, 1): (U32, "feed"),
    (drive_od.FEED_CONSTANT, 2): (U32, "shaft revolutions"),
    (drive_od.INTERPOLATION_TIME_PERIOD, 1): (U8, "interpolation time period value"),
    (drive_od.INTERPOLATION_TIME_PERIOD, 2): (I8, "interpolation time index"),
}
"""The optional standard objects the master reads, with their CiA 301/402 types."""

REQUIRED_IN_EDS = (drive_od.DEVICE_TYPE, drive_od.IDENTITY, drive_od.CONTROLWORD, drive_od.STATUSWORD,
                   drive_od.MODES_OF_OPERATION, drive_od.MODES_OF_OPERATION_DISPLAY, drive_od.POSITION_ACTUAL_VALUE,
                   drive_od.TARGET_POSITION, drive_od.SUPPORTED_DRIVE_MODES, 0x1400, 0x1600, 0x1800, 0x1A00)
"""What a drive's EDS must list for the master to drive it."""

_MODES = {1: "PP", 3: "PV", 4: "PT", 6: "HM", 7: "IP", 8: "CSP", 9: "CSV", 10: "CST"}


@dataclass
class DriveReport:
    """One drive as read: ``objects`` holds every optional object's value (None: absent), ``problems`` why the
    master cannot drive it (empty: it can)."""

    leg: int
    node_id: int
    vendor_id: int = 0
    product_code: int = 0
    device_type: int = 0
    modes: int = 0
    profile: DriveProfile | None = None
    objects: dict[tuple[int, int], int | None] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    def has(self, index: int, subindex: int = 0) -> bool:
        return self.objects.get((index, subindex)) is not None

    @property
    def unit(self) -> PositionUnit | None:
        """The position unit 0x60A8 states (None without it)."""
        value = self.objects.get((drive_od.SI_UNIT_POSITION, 0))
        return None if value is None else decode_position_unit(value)

    @property
    def consumes_heartbeat(self) -> bool:
        """Whether the drive can watch the master's heartbeat (0x1016)."""
        return self.has(drive_od.CONSUMER_HEARTBEAT_TIME, 1)

    @property
    def guarded(self) -> bool:
        """Whether the master watches it by node guarding (and it the master by life guarding): it cannot consume
        heartbeats and has 0x100C and 0x100D."""
        return (not self.consumes_heartbeat and self.has(drive_od.GUARD_TIME)
                and self.has(drive_od.LIFE_TIME_FACTOR))

    @property
    def watch(self) -> str:
        """How the master and the drive watch each other, in words."""
        if self.consumes_heartbeat and self.has(drive_od.PRODUCER_HEARTBEAT_TIME):
            return "heartbeats both ways (0x1016, 0x1017)"
        if self.guarded:
            return "node guarding and life guarding (0x100C, 0x100D)"
        return "none"

    def mode_names(self) -> list[str]:
        return [_MODES.get(bit + 1, f"mode {bit + 1}") for bit in range(32) if self.modes >> bit & 1]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (``rig table check --json``)."""
        unit = self.unit
        present = sorted({index for (index, _), value in self.objects.items() if value is not None})
        absent = sorted({index for (index, _), value in self.objects.items() if value is None} - set(present))
        return {"leg": self.leg, "node_id": self.node_id, "vendor_id": self.vendor_id,
                "product_code": self.product_code, "device_type": self.device_type, "modes": self.mode_names(),
                "profile": None if self.profile is None else self.profile.name,
                "profile_features": [] if self.profile is None else list(self.profile.features),
                "position_unit": None if unit is None else str(unit), "watch": self.watch,
                "optional_used": [f"0x{i:04X}" for i in present], "optional_missing": [f"0x{i:04X}" for i in absent],
                "factors": {f"0x{i:04X}:{s}": v for (i, s), v in self.objects.items()
                            if i in (drive_od.POSITION_ENCODER_RESOLUTION, drive_od.GEAR_RATIO,
                                     drive_od.FEED_CONSTANT) and v is not None},
                "problems": list(self.problems)}


def eds_objects(path: Path, node_id: int, where: str) -> canopen.ObjectDictionary:
    """The object dictionary of the EDS at ``path`` (configured ``where``: "FILE:LINE: drives.leg.N");
    :class:`DriveSetupError` naming both files when it does not parse or lacks what the master needs."""
    try:
        od = canopen.import_od(str(path), node_id)
    except Exception as exc:  # configparser's and canopen's errors alike: the file is not an EDS we can read
        line = getattr(exc, "lineno", None) or next((e[0] for e in getattr(exc, "errors", ())), None)
        raise DriveSetupError(f"{where}.eds: {path}{f':{line}' if line else ''}: not a readable EDS "
                              f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    missing = [f"0x{index:04X}" for index in REQUIRED_IN_EDS if index not in od]
    if missing:
        raise DriveSetupError(f"{where}.eds: {path}: lacks {', '.join(missing)}, which the master needs of a CSP "
                              "drive")
    return od


def _in_eds(od: canopen.ObjectDictionary, index: int, subindex: int) -> bool:
    if index not in od:
        return False
    obj = od[index]
    return isinstance(obj, canopen.objectdictionary.ODVariable) or subindex in obj


def inspect_drive(sdo: NodeSdo, leg: int, eds: canopen.ObjectDictionary | None = None) -> DriveReport:
    """Read what the drive on ``sdo`` is (module docstring); with its ``eds``, objects the EDS lacks are not asked
    for. A drive the master cannot drive has its reasons in ``problems``."""
    report = DriveReport(leg, sdo.node_id)
    report.device_type = sdo.read(drive_od.DEVICE_TYPE, 0, U32, "device type")
    report.vendor_id = sdo.read(drive_od.IDENTITY, 1, U32, "vendor-ID")
    report.product_code = sdo.read(drive_od.IDENTITY, 2, U32, "product code")
    report.profile = profile_of(report.vendor_id, report.product_code)
    if report.device_type & 0xFFFF != drive_od.CIA402_PROFILE:
        report.problems.append(f"device type 0x{report.device_type:08X} (0x1000) is not a CiA 402 drive")
        return report
    report.modes = sdo.read(drive_od.SUPPORTED_DRIVE_MODES, 0, U32, "supported drive modes")
    if not report.modes & drive_od.SUPPORTED_MODE_CSP:
        report.problems.append(f"no cyclic synchronous position mode: 0x6502 = 0x{report.modes:08X} "
                               f"({', '.join(report.mode_names()) or 'no modes'}); the master plays legs in CSP only")
    for (index, subindex), (kind, name) in OPTIONAL.items():
        if eds is not None and not _in_eds(eds, index, subindex):
            report.objects[(index, subindex)] = None
            continue
        report.objects[(index, subindex)] = sdo.probe(index, subindex, kind, name)
    if not (report.consumes_heartbeat or report.guarded):
        report.problems.append("it can watch neither the master's heartbeat (no 0x1016) nor its node guarding (no "
                               "0x100C/0x100D): it would not stop its leg when the master falls silent")
    if not (report.has(drive_od.PRODUCER_HEARTBEAT_TIME) or report.guarded):
        report.problems.append("it can be watched neither by its heartbeat (no 0x1017) nor by node guarding")
    return report


def require_drivable(report: DriveReport, url: str) -> None:
    """:class:`DriveSetupError` with the first of the report's problems."""
    if report.problems:
        raise DriveSetupError(f"{url}: leg {report.leg} (node {report.node_id}, vendor 0x{report.vendor_id:08X} "
                              f"product 0x{report.product_code:08X}): {report.problems[0]}")
