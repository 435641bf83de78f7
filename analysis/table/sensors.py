"""The ``[sensors]`` table of the rig configuration: each accelerometer's calibration sheet (``docs/sensors.md``).

```toml
[sensors]
overdue = "warn"               # a sensor past its due date: "warn" at start (default) or "refuse" to run

[sensors.0]                    # the accelerometer with id 0 (the session file's accel/0)
model = "PCB 356A16"
serial = "LW231455"
sensitivity = 100.0            # 0.001 … 1e5 in sensitivity_unit
sensitivity_unit = "mV/g"      # mV/g, V/g, mV/(m/s^2), V/(m/s^2), pC/g or pC/(m/s^2)
range = 5.0                    # full scale, read as ±: 0.01 … 1000 g (0.0981 … 9807 m/s²)
range_unit = "g"               # g or m/s^2
calibrated = 2026-01-15        # a TOML date (or "2026-01-15")
due = 2027-01-15               # after calibrated
place_m = [0.30, -0.20, 0.05]  # where it sits, plate frame [m]: x downhill, z up from the plate; each within ±20 m
axes = ["+x", "+y", "+z"]      # the plate axis each of its own axes (1, 2, 3) points along: each of x, y, z once
noise_floor_m_s2 = 0.03        # optional: its noise at rest, RMS per axis [m/s²], 1e-6 … 1 and below the range

[sensors.tilt.1]               # the tilt sensor of body 1 (the sequence's body_id: the session file's tilt/1)
model = "Jewell A602"
serial = "T-0423"
range = 90.0                   # full scale, read as ±: 1° … 180° (0.01745 … 3.1416 rad)
range_unit = "deg"             # deg or rad
calibrated = 2026-02-01
due = 2027-02-01               # after calibrated
```

An accelerometer is named by its id (a whole number, 0 … 255); every key of its sheet is required but
``noise_floor_m_s2`` (without it the noise-floor suspender leaves the sensor alone: ``rig.orchestrator.noise``).
A tilt sensor is named by its body's id (1 … 255: the sequence's ``body_id``), under ``tilt``; every key of its
sheet is required. ``overdue`` is optional. Errors are ``FILE:LINE: sensors.ID.KEY: problem``. The date is not
checked against today when the file is read (a session's stored configuration must stay readable a year on):
:func:`overdue` does it at start.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import date
from typing import Any

import numpy as np

from analysis.body import G
from analysis.table.toml_check import TomlChecker, shown

OVERDUE_POLICIES = ("warn", "refuse")
"""What a sensor past its due date does at start."""

SENSITIVITY_UNITS = {"mV/g": 1e-3 / G, "V/g": 1.0 / G, "mV/(m/s^2)": 1e-3, "V/(m/s^2)": 1.0,
                     "pC/g": 1e-12 / G, "pC/(m/s^2)": 1e-12}
"""Sensitivity units an accelerometer may be given in, with their factor to SI (V or C per m/s²)."""

RANGE_UNITS = {"g": G, "m/s^2": 1.0}
"""Acceleration units of a range, with their factor to m/s²."""

SENSITIVITY_RANGE = (1e-3, 1e5)
"""A sensitivity as written, in its own unit (0.001 mV/g is a dead sensor, 1e5 mV/g beyond any seismic one)."""

RANGE_M_S2 = (0.01 * G, 1000.0 * G)
"""A full scale [m/s²]: 0.01 g to 1000 g."""

NOISE_FLOOR_M_S2 = (1e-6, 1.0)
"""A noise floor, RMS per axis [m/s²]: 0.1 µg (the best seismic sensors) to 0.1 g (no accelerometer worth a sheet)."""

PLATE_AXES = ("+x", "+y", "+z")
"""The axes of a sensor mounted along the plate's: its readings are the plate frame's."""

MAX_PLACE_M = 20.0
"""Largest |coordinate| of a sensor's place [m]."""

TILT_RANGE_UNITS = {"deg": math.pi / 180.0, "rad": 1.0}
"""Angle units of a tilt sensor's range, with their factor to rad."""

TILT_RANGE_RAD = (math.radians(1.0), math.pi)
"""A tilt sensor's full scale [rad]: 1° to 180°."""

MAX_BODY_ID = 255
"""Largest body id of a tilt sensor's sheet."""

MAX_SENSOR_ID = 255
"""Largest accelerometer id."""

_SENSOR_KEYS = ("model", "serial", "sensitivity", "sensitivity_unit", "range", "range_unit", "calibrated", "due",
                "place_m", "axes")
_OPTIONAL_KEYS = ("noise_floor_m_s2",)
_TILT_KEYS = ("model", "serial", "range", "range_unit", "calibrated", "due")
_AXES = ("x", "y", "z")
_TEXT_LEN = 64


@dataclass(frozen=True)
class SensorSheet:
    """One accelerometer's calibration sheet. ``sensitivity`` is as written, in ``sensitivity_unit``; ``range_m_s2``
    the full scale [m/s², read as ±]; ``place_m`` (x, y, z) in the plate frame [m] (x downhill, z up);
    ``axes`` the plate axis each of the sensor's three axes points along, signed (``"+x"``, ``"-y"``, …);
    ``noise_floor_m_s2`` its noise at rest, RMS of each axis [m/s²] (None: not given, not watched);
    ``source`` and ``due_line`` say where it was written (the file, the line of its ``due`` key) for messages."""

    sensor: str
    model: str
    serial: str
    sensitivity: float
    sensitivity_unit: str
    range_m_s2: float
    calibrated: date
    due: date
    place_m: tuple[float, float, float]
    axes: tuple[str, str, str]
    noise_floor_m_s2: float | None = None
    source: str = field(default="", compare=False)
    due_line: int | None = field(default=None, compare=False)

    @property
    def due_key(self) -> str:
        """The dotted key of its due date."""
        return f"sensors.{self.sensor}.due"

    def mounting(self) -> np.ndarray:
        """The 3×3 matrix ``A`` that turns a vector in the plate frame into the sensor's own axes (``s = A f``; a
        signed permutation, so ``f = Aᵀ s``): row i has ``±1`` in the column of the plate axis its axis i points
        along."""
        matrix = np.zeros((3, 3))
        for row, axis in enumerate(self.axes):
            matrix[row, _AXES.index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
        return matrix

    def overdue_problem(self) -> str:
        """What an overdue sheet is, in words (no place)."""
        return (f"accelerometer {self.sensor} ({self.model}, serial {self.serial}) was due for calibration on "
                f"{self.due.isoformat()}")

    def to_dict(self) -> dict[str, Any]:
        """The sheet in the TOML layout, SI range, dates as ISO text (JSON has no dates)."""
        return {"model": self.model, "serial": self.serial, "sensitivity": self.sensitivity,
                "sensitivity_unit": self.sensitivity_unit, "range": self.range_m_s2, "range_unit": "m/s^2",
                "calibrated": self.calibrated.isoformat(), "due": self.due.isoformat(),
                "place_m": list(self.place_m), "axes": list(self.axes),
                **({} if self.noise_floor_m_s2 is None else {"noise_floor_m_s2": self.noise_floor_m_s2})}


@dataclass(frozen=True)
class TiltSheet:
    """One body's tilt sensor's calibration sheet (the overturn detector's channel: the body's rocking angle
    relative to the plate, > 0 towards the low side). ``body`` the body's id as text; ``range_rad`` the full scale
    [rad, read as ±]; ``source`` and ``due_line`` as :class:`SensorSheet`'s."""

    body: str
    model: str
    serial: str
    range_rad: float
    calibrated: date
    due: date
    source: str = field(default="", compare=False)
    due_line: int | None = field(default=None, compare=False)

    @property
    def due_key(self) -> str:
        """The dotted key of its due date."""
        return f"sensors.tilt.{self.body}.due"

    def overdue_problem(self) -> str:
        """What an overdue sheet is, in words (no place)."""
        return (f"the tilt sensor of body {self.body} ({self.model}, serial {self.serial}) was due for calibration "
                f"on {self.due.isoformat()}")

    def to_dict(self) -> dict[str, Any]:
        """The sheet in the TOML layout, range in rad, dates as ISO text."""
        return {"model": self.model, "serial": self.serial, "range": self.range_rad, "range_unit": "rad",
                "calibrated": self.calibrated.isoformat(), "due": self.due.isoformat()}


@dataclass(frozen=True)
class SensorSheets:
    """The ``[sensors]`` table: the accelerometers' sheets by sensor name (the accelerometer id as text), the
    tilt sensors' by body id (as text) and the overdue policy."""

    sheets: Mapping[str, SensorSheet] = field(default_factory=dict)
    overdue: str = "warn"
    tilts: Mapping[str, TiltSheet] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The table in the TOML layout (``to_dict`` per sheet; the tilt sensors under ``tilt``)."""
        tilts = {"tilt": {body: sheet.to_dict() for body, sheet in self.tilts.items()}} if self.tilts else {}
        return {"overdue": self.overdue, **{name: sheet.to_dict() for name, sheet in self.sheets.items()}, **tilts}

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, SensorSheets) and self.overdue == other.overdue
                and dict(self.sheets) == dict(other.sheets) and dict(self.tilts) == dict(other.tilts))

    def __hash__(self) -> int:
        return hash((self.overdue, tuple(sorted(self.sheets.items())), tuple(sorted(self.tilts.items()))))


def overdue(sheets: SensorSheets, today: date) -> list[SensorSheet | TiltSheet]:
    """The sheets (accelerometers', then tilt sensors') whose calibration is due on or before ``today``."""
    every: list[SensorSheet | TiltSheet] = [*sheets.sheets.values(), *sheets.tilts.values()]
    return [sheet for sheet in every if sheet.due <= today]


def read_sensors(checker: TomlChecker, value: Any) -> SensorSheets:
    """The ``[sensors]`` table read by ``checker``; errors (the checker's) name the line and key."""
    if value is None:
        return SensorSheets()
    path = ("sensors",)
    names = [key for key in value if key not in ("overdue", "tilt")] if isinstance(value, Mapping) else []
    top = checker.table(value, path, ("overdue", "tilt", *names))
    policy = top.get("overdue", "warn")
    if policy not in OVERDUE_POLICIES:
        raise checker.error((*path, "overdue"), f"expected one of {', '.join(OVERDUE_POLICIES)}, got {shown(policy)}")
    sheets = {}
    for name in names:
        if not name.isdigit() or int(name) > MAX_SENSOR_ID or str(int(name)) != name:
            raise checker.error((*path, name), f"expected an accelerometer id from 0 to {MAX_SENSOR_ID} as the "
                                               f"sensor's name, got {shown(name)}")
        sheets[name] = _sheet(checker, (*path, name), top[name])
    return SensorSheets(sheets, policy, _tilts(checker, top.get("tilt")))


def _tilts(checker: TomlChecker, value: Any) -> dict[str, TiltSheet]:
    """The ``[sensors.tilt]`` table: a sheet per body id."""
    if value is None:
        return {}
    path = ("sensors", "tilt")
    bodies = list(value) if isinstance(value, Mapping) else []
    table = checker.table(value, path, bodies)
    tilts = {}
    for body in bodies:
        if not body.isdigit() or not 1 <= int(body) <= MAX_BODY_ID or str(int(body)) != body:
            raise checker.error((*path, body), f"expected a body id from 1 to {MAX_BODY_ID} (the sequence's "
                                               f"body_id) as the tilt sensor's name, got {shown(body)}")
        tilts[body] = _tilt_sheet(checker, (*path, body), table[body])
    return tilts


def _full_scale(checker: TomlChecker, table: Mapping[str, Any], path: tuple[str, ...], units: dict[str, float],
                limits: tuple[float, float], kind: str, high_format: str) -> float:
    """A sheet's ``range`` in its ``range_unit`` (one of ``units``: the SI value of one unit), checked against
    ``limits`` [SI] and returned in SI units; ``kind`` names the unit wanted in the error."""
    unit = table["range_unit"]
    if unit not in units:
        raise checker.error((*path, "range_unit"), f"expected {kind}, one of {', '.join(units)}, got {shown(unit)}")
    factor = units[unit]
    low, high = limits
    return checker.ranged(table["range"], (*path, "range"), low / factor * (1 - 1e-12), high / factor * (1 + 1e-12),
                          f"a full scale from {low / factor:.4g} to {high / factor:{high_format}} {unit}") * factor


def _calibration_dates(checker: TomlChecker, table: Mapping[str, Any], path: tuple[str, ...]) -> tuple[date, date]:
    """A sheet's ``calibrated`` and ``due`` dates, the due date after the calibration."""
    calibrated = _date(checker, table["calibrated"], (*path, "calibrated"))
    due = _date(checker, table["due"], (*path, "due"))
    if due <= calibrated:
        raise checker.error((*path, "due"), f"due date {due.isoformat()} is not after the calibration date "
                                            f"{calibrated.isoformat()}")
    return calibrated, due


def _tilt_sheet(checker: TomlChecker, path: tuple[str, ...], value: Any) -> TiltSheet:
    table = checker.table(value, path, _TILT_KEYS)
    missing = [key for key in _TILT_KEYS if key not in table]
    if missing:
        raise checker.error(path, f"missing {', '.join(missing)}")
    text = {key: _text(checker, table[key], (*path, key)) for key in ("model", "serial")}
    full_scale = _full_scale(checker, table, path, TILT_RANGE_UNITS, TILT_RANGE_RAD, "an angle unit", ".5g")
    calibrated, due = _calibration_dates(checker, table, path)
    return TiltSheet(path[-1], text["model"], text["serial"], full_scale, calibrated, due, checker.source,
                     checker.line((*path, "due")))


def _sheet(checker: TomlChecker, path: tuple[str, ...], value: Any) -> SensorSheet:
    table = checker.table(value, path, (*_SENSOR_KEYS, *_OPTIONAL_KEYS))
    missing = [key for key in _SENSOR_KEYS if key not in table]
    if missing:
        raise checker.error(path, f"missing {', '.join(missing)}")
    text = {key: _text(checker, table[key], (*path, key)) for key in ("model", "serial")}
    unit = table["sensitivity_unit"]
    if unit not in SENSITIVITY_UNITS:
        raise checker.error((*path, "sensitivity_unit"), f"expected an accelerometer's sensitivity unit, one of "
                                                         f"{', '.join(SENSITIVITY_UNITS)}, got {shown(unit)}")
    sensitivity = checker.ranged(table["sensitivity"], (*path, "sensitivity"), *SENSITIVITY_RANGE,
                                 f"a sensitivity from {SENSITIVITY_RANGE[0]:g} to {SENSITIVITY_RANGE[1]:g} {unit}")
    full_scale = _full_scale(checker, table, path, RANGE_UNITS, RANGE_M_S2, "an acceleration unit", ".4g")
    calibrated, due = _calibration_dates(checker, table, path)
    place = table["place_m"]
    if not isinstance(place, list) or len(place) != 3:
        raise checker.error((*path, "place_m"), f"expected [x, y, z] in metres (plate frame), got {shown(place)}")
    xyz = tuple(checker.ranged(c, (*path, "place_m"), -MAX_PLACE_M, MAX_PLACE_M,
                               f"coordinates in metres within ±{MAX_PLACE_M:g} m") for c in place)
    axes = table["axes"]
    wanted = "the plate axis of each of the sensor's axes, e.g. [\"+x\", \"+y\", \"+z\"] (each of x, y, z once)"
    if (not isinstance(axes, list) or len(axes) != 3 or not all(isinstance(a, str) and len(a) == 2
                                                                and a[0] in "+-" and a[1] in _AXES for a in axes)
            or sorted(a[1] for a in axes) != list(_AXES)):
        raise checker.error((*path, "axes"), f"expected {wanted}, got {shown(axes)}")
    noise = None if "noise_floor_m_s2" not in table else _noise_floor(checker, table["noise_floor_m_s2"],
                                                                     (*path, "noise_floor_m_s2"), full_scale)
    return SensorSheet(path[-1], text["model"], text["serial"], sensitivity, unit, full_scale, calibrated, due,
                       (xyz[0], xyz[1], xyz[2]), (axes[0], axes[1], axes[2]), noise, checker.source,
                       checker.line((*path, "due")))


def _noise_floor(checker: TomlChecker, value: Any, path: tuple[str, ...], full_scale: float) -> float:
    """A noise floor [m/s² RMS] in :data:`NOISE_FLOOR_M_S2` and below the sensor's ``full_scale`` [m/s²]."""
    low, high = NOISE_FLOOR_M_S2
    floor = checker.ranged(value, path, low, high, f"a noise floor from {low:g} to {high:g} m/s² RMS")
    if floor >= full_scale:
        raise checker.error(path, f"noise floor {floor:g} m/s² RMS is not below the sensor's full scale "
                                  f"{full_scale:.4g} m/s²")
    return floor


def _text(checker: TomlChecker, value: Any, path: tuple[str, ...]) -> str:
    if not isinstance(value, str) or not value.strip() or len(value) > _TEXT_LEN:
        raise checker.error(path, f"expected text of 1 to {_TEXT_LEN} characters, got {shown(value)}")
    return value


def _date(checker: TomlChecker, value: Any, path: tuple[str, ...]) -> date:
    """A TOML date (``2027-01-15``, not a date-time) or its ISO text."""
    if isinstance(value, date) and type(value) is date:
        return value
    if isinstance(value, str):
        try:
            parsed = date.fromisoformat(value)
        except ValueError:
            parsed = None
        if parsed is not None and len(value) == 10:
            return parsed
    raise checker.error(path, f"expected a date such as 2027-01-15, got {shown(value)}")


def clipped_rows(xyz: np.ndarray, full_scale: float) -> np.ndarray:
    """Indices of the rows of ``xyz`` (k, 3) [m/s²] with some axis at or beyond ``full_scale`` [m/s², ±]: the
    readings a sensor of that range cannot have measured truly."""
    return np.flatnonzero((np.abs(np.asarray(xyz, dtype=float)) >= full_scale).any(axis=1))
