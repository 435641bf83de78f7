"""The table's motion limits: Table IV's translational axes and the tilt, and the checks of their fields.

SI inside: m, m/s, m/s² for the axes, rad, rad/s, rad/s², rad/s³ for the tilt; every limit is the magnitude of a ±
bound. :class:`TableModelError` is the error of every part of the table model (`analysis.table.model`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from analysis.body import G
from analysis.errors import AnalysisInputError
from analysis.table.toml_check import is_number
from analysis.table.toml_lines import suggest as _suggest

DEG = math.pi / 180.0
"""One degree [rad]; every degree value of the table model (defaults and files) is converted with it."""

AXES = ("surge", "lateral", "heave")
"""The translational axes of Table IV, in pose column order 0, 1, 2."""

TILTS = ("roll", "pitch")
"""The limited rotations, in pose column order 3, 4."""


class TableModelError(AnalysisInputError):
    """A bad table configuration; from a file the message starts with ``FILE:LINE: key:``."""


Check = Callable[[float, object], str | None]
"""A validator: (value in SI, value as given) → what is wrong, or None."""


def positive(value: float, shown: object) -> str | None:
    """A `Check`: finite and > 0."""
    return None if math.isfinite(value) and value > 0 else f"must be a finite number > 0, got {shown!r}"


def non_negative(value: float, shown: object) -> str | None:
    """A `Check`: finite and >= 0."""
    return None if math.isfinite(value) and value >= 0 else f"must be a finite number >= 0, got {shown!r}"


def half_angle(value: float, shown: object) -> str | None:
    """A `Check` of a hexapod layout's half angle [rad]: in [0, π/3)."""
    ok = math.isfinite(value) and 0 <= value < math.pi / 3
    return None if ok else f"must be at least 0 and below 60° (π/3 rad), got {shown!r}"


def number_problem(value: object, check: Check) -> str | None:
    """What is wrong with a number given in SI, or None."""
    return check(float(value), value) if is_number(value) else f"expected a number, got {value!r}"


def check_fields(owner: object, check: Check, names: tuple[str, ...]) -> None:
    """Validate the named attributes of a frozen dataclass and store them as floats."""
    for name in names:
        value = getattr(owner, name)
        problem = number_problem(value, check)
        if problem:
            raise TableModelError(f"{type(owner).__name__}.{name}: {problem}")
        object.__setattr__(owner, name, float(value))


@dataclass(frozen=True)
class AxisLimits:
    """The ± limits of one translational axis: displacement [m], velocity [m/s], acceleration [m/s²]."""

    displacement: float
    velocity: float
    acceleration: float

    def __post_init__(self) -> None:
        check_fields(self, positive, ("displacement", "velocity", "acceleration"))


@dataclass(frozen=True)
class TiltLimits:
    """The limits of roll and pitch: |angle| [rad], rate [rad/s], acceleration [rad/s²], jerk [rad/s³].

    Rate, acceleration and jerk bound the static tilt ramp to β and back; Table IV has no rotations,
    the defaults (10°, 2°/s, 2°/s², 4°/s³) are the rig's.
    """

    angle: float = 10 * DEG
    rate: float = 2 * DEG
    acceleration: float = 2 * DEG
    jerk: float = 4 * DEG

    def __post_init__(self) -> None:
        check_fields(self, positive, ("angle", "rate", "acceleration", "jerk"))


@dataclass(frozen=True)
class TableLimits:
    """The nominal motion limits of the table: three translational axes and the tilt."""

    surge: AxisLimits
    lateral: AxisLimits
    heave: AxisLimits
    tilt: TiltLimits = field(default_factory=TiltLimits)

    def axis(self, name: str) -> AxisLimits:
        """The limits of axis ``name``: ``"surge"``, ``"lateral"`` or ``"heave"``."""
        if name not in AXES:
            raise TableModelError(f"unknown axis {name!r}: expected one of {', '.join(AXES)}{_suggest(name, AXES)}")
        return getattr(self, name)


TABLE_IV = TableLimits(
    surge=AxisLimits(displacement=0.25, velocity=0.5, acceleration=0.6 * G),
    lateral=AxisLimits(displacement=0.25, velocity=0.5, acceleration=0.6 * G),
    heave=AxisLimits(displacement=0.18, velocity=0.3, acceleration=0.7 * G),
)
"""The paper's Table IV (nominal limits of the shake table) with the default tilt limits."""
