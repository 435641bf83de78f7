"""Sensor sheets as the rig configuration's ``[sensors]`` TOML (docs/sensors.md), for the tests that read them: an
accelerometer's or a tilt sensor's sheet with the values a test gives (the others plain, never overdue), the
``[sensors]`` table of some sheets, and that text written as a rig configuration file."""

from __future__ import annotations

import json
from collections.abc import Sequence
from datetime import date
from pathlib import Path

_ACCELEROMETER: dict[str, object] = {
    "model": "PCB 356A16", "serial": None, "sensitivity": 100.0, "sensitivity_unit": "mV/g", "range": 5.0,
    "range_unit": "g", "calibrated": date(2026, 1, 15), "due": date(2099, 1, 15), "place_m": [0.0, 0.0, 0.0],
    "axes": ["+x", "+y", "+z"], "noise_floor_m_s2": None}
"""An accelerometer's keys in the order written, each with its value where the test gives none (None: left out; the
serial is the sensor's own, :func:`accelerometer`)."""

_TILT: dict[str, object] = {
    "model": "Jewell A602", "serial": "T-0423", "range": 90.0, "range_unit": "deg", "calibrated": date(2026, 2, 1),
    "due": date(2099, 2, 1)}
"""A tilt sensor's keys in the order written, each with its value where the test gives none."""


def accelerometer(sensor: int, **values: object) -> str:
    """The sheet ``[sensors.SENSOR]`` of accelerometer ``sensor``: one key a line (model, serial, sensitivity,
    sensitivity_unit, range, range_unit, calibrated, due, place_m, axes, noise_floor_m_s2: the header on line 1,
    ``due`` on line 9), ``values`` in place of a plain PCB 356A16 of 100 mV/g and ±5 g at the plate's centre along
    its axes, serial ``LW2314<55 + sensor>``, calibrated 2026-01-15, due 2099-01-15, no noise floor. A value None
    leaves its key out."""
    return _sheet(f"sensors.{sensor}", _ACCELEROMETER, {"serial": f"LW2314{55 + sensor}", **values})


def tilt_sensor(body: int, **values: object) -> str:
    """The sheet ``[sensors.tilt.BODY]`` of body ``body``'s tilt sensor: one key a line (model, serial, range,
    range_unit, calibrated, due: ``due`` on line 7), ``values`` in place of a Jewell A602 serial T-0423 of ±90°
    calibrated 2026-02-01, due 2099-02-01. A value None leaves its key out."""
    return _sheet(f"sensors.tilt.{body}", _TILT, values)


def sensors_toml(*sheets: str, overdue: str | None = None) -> str:
    """A rig configuration of a ``[sensors]`` table: its ``overdue`` policy first when given (then the first sheet
    starts on line 4), then ``sheets`` in order, a blank line between two."""
    policy = [f"[sensors]\noverdue = {_toml(overdue)}\n"] if overdue is not None else []
    return "\n".join([*policy, *sheets])


def write_rig(directory: Path, text: str) -> Path:
    """``text`` written as the rig configuration ``directory/rig.toml``; its path."""
    path = directory / "rig.toml"
    path.write_text(text)
    return path


def _sheet(table: str, defaults: dict[str, object], values: dict[str, object]) -> str:
    unknown = values.keys() - defaults.keys()
    if unknown:
        raise TypeError(f"no such key of [{table}]: {', '.join(sorted(unknown))}")
    merged = {**defaults, **values}
    lines = [f"{key} = {_toml(value)}" for key, value in merged.items() if value is not None]
    return "\n".join([f"[{table}]", *lines, ""])


def _toml(value: object) -> str:
    """``value`` (text, a date, a number or a list of them) as a TOML value."""
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, date):
        return value.isoformat()
    if isinstance(value, Sequence):
        return "[" + ", ".join(_toml(item) for item in value) + "]"
    return repr(value)
