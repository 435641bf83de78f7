"""A leg drive's position unit, established at connect: what the drive states (0x60A8, 0x608F, 0x6091, 0x6092)
checked against what the rig configuration says of it (``[drives]``, :mod:`analysis.table.drives`); the result is the
leg's :class:`~protocols.canopen.scaling.LegScaling`, the one place where metres become drive units.

- 0x60A8 in metres with a prefix (the project's drives: µm): 10^−prefix units per metre. A scale in the
  configuration must agree.
- 0x60A8 in increments (EPOS4, Everest): the scale must come from the configuration (``increments_per_metre``, or
  the encoder's increments × the gear ratio / the screw's lead).
- no 0x60A8: the configuration's ``position_unit`` (the integrator vouches for it) and, for increments, its scale.
- any other unit, or none established: refused.

Where the drive has them, its factors must agree with the configuration's: encoder increments per motor revolution
(0x608F sub 1 / sub 2), the gear ratio (0x6091 sub 1 / sub 2), and the feed constant (0x6092 sub 1 / sub 2, in the
drive's position units per shaft revolution: the lead × the units per metre). A drive that disagrees is refused
before it is enabled, with the values read and expected.
"""

from __future__ import annotations

import math

from analysis.table.drives import POSITION_UNITS, LegDriveSettings
from analysis.table.model import HexapodGeometry
from drivers.canopen.sdo import DriveSetupError
from drivers.canopen.survey import DriveReport
from protocols.canopen import LegRangeError, LegScaling
from protocols.canopen import od as drive_od

_TOLERANCE = 1e-6
"""Relative difference below which a factor read agrees with the one expected."""


def _ratio(report: DriveReport, index: int) -> float | None:
    """sub 1 / sub 2 of a factor object (None when absent, or a zero denominator)."""
    top, bottom = report.objects.get((index, 1)), report.objects.get((index, 2))
    return None if top is None or not bottom else top / bottom


def _refuse(url: str, report: DriveReport, settings: LegDriveSettings, problem: str) -> DriveSetupError:
    where = f" ({settings.where})" if settings.where else ""
    return DriveSetupError(f"{url}: leg {report.leg} (node {report.node_id}){where}: {problem}; refused before "
                           "enabling it")


def leg_scaling(url: str, report: DriveReport, settings: LegDriveSettings, geometry: HexapodGeometry) -> LegScaling:
    """The leg's scaling (module docstring), or a :class:`DriveSetupError` with the values read and expected."""
    unit = report.unit
    configured = settings.per_metre
    if unit is not None and unit.per_metre is not None:
        per_metre = unit.per_metre
        if configured is not None and not math.isclose(configured, per_metre, rel_tol=_TOLERANCE):
            raise _refuse(url, report, settings, f"its position unit is {unit} ({per_metre:g} per metre, 0x60A8), "
                                                 f"the configuration expects {configured:g} per metre")
        if settings.position_unit is not None and POSITION_UNITS[settings.position_unit] != per_metre:
            raise _refuse(url, report, settings, f"its position unit is {unit} (0x60A8), the configuration expects "
                                                 f"{settings.position_unit}")
    elif (unit is not None and unit.increments) or (unit is None and settings.position_unit == "increments"):
        stated = "0x60A8 = increments" if unit is not None else "no 0x60A8; position_unit = increments"
        if settings.position_unit not in (None, "increments"):
            raise _refuse(url, report, settings, f"its position unit is increments (0x60A8), the configuration "
                                                 f"expects {settings.position_unit}")
        if configured is None:
            raise _refuse(url, report, settings, f"its positions are encoder increments ({stated}) and the rig "
                                                 "configuration gives no scale for them: set [drives] "
                                                 "increments_per_metre, or encoder_increments, gear_ratio and feed_m")
        per_metre = configured
    elif unit is None and settings.position_unit is not None:
        per_metre = POSITION_UNITS[settings.position_unit] or 0.0
    elif unit is None:
        raise _refuse(url, report, settings, "the master cannot establish its position unit: the drive has no "
                                             "0x60A8 and the rig configuration states no [drives] position_unit")
    else:
        raise _refuse(url, report, settings, f"its position unit is {unit} (0x60A8 = 0x"
                                             f"{report.objects[(drive_od.SI_UNIT_POSITION, 0)]:08X}), not a length "
                                             "the master can convert metres to")
    _check_factors(url, report, settings, per_metre)
    try:
        return LegScaling(geometry.leg_min, geometry.leg_max, per_metre, settings.polarity)
    except LegRangeError as exc:
        raise _refuse(url, report, settings, str(exc)) from None


def _check_factors(url: str, report: DriveReport, settings: LegDriveSettings, per_metre: float) -> None:
    """The drive's 0x608F, 0x6091 and 0x6092 against the configuration's factors, where both have them."""
    expected = {}
    if settings.encoder_increments is not None:
        expected[drive_od.POSITION_ENCODER_RESOLUTION] = ("encoder increments per motor revolution",
                                                          settings.encoder_increments)
    if settings.gear_ratio is not None:
        expected[drive_od.GEAR_RATIO] = ("motor revolutions per shaft revolution", settings.gear_ratio)
    if settings.feed_m is not None:
        expected[drive_od.FEED_CONSTANT] = ("feed per shaft revolution [drive units]", settings.feed_m * per_metre)
    for index, (name, value) in expected.items():
        read = _ratio(report, index)
        if read is not None and not math.isclose(read, value, rel_tol=_TOLERANCE):
            top, bottom = report.objects[(index, 1)], report.objects[(index, 2)]
            raise _refuse(url, report, settings, f"its {name} is {read:g} (0x{index:04X} = {top}/{bottom}), the "
                                                 f"configuration expects {value:g}")
