"""The rig configuration file: its TOML reader and writer (`TableConfiguration`, the parts of a table model).

Sections ``[table]``, ``[limits.surge|lateral|heave|tilt]``, ``[hexapod]``, ``[dynamics]``, ``[controller]``,
``[sensors.N]``, ``[limit_detectors.…]`` and ``[network]``; every one may be left out (Table IV and the default
geometry). Keys carry their unit in their name (``_m``, ``_m_s``, ``_g``, ``_deg``, ``_rad``, ``_hz``, ``_s``);
every number has a physical range. Only a regular file of at most 1 MiB is read. Errors raise
`analysis.table.limits.TableModelError` ``FILE:LINE: dotted.key: problem``. :func:`configuration_dict` writes the
same layout in SI keys (``acceleration_m_s2``, ``angle_rad``, explicit joints): reading it back gives an equal
configuration exactly.

The layout with every key and its range: docs/rig-configuration.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from analysis.body import G
from analysis.table.drives import DriveSettings, read_drives
from analysis.table.dynamics import TableDynamics
from analysis.table.kinematics import HexapodGeometry, geometry_problem, symmetric_joints
from analysis.table.limit_detectors import LimitDetectors, read_limit_detectors
from analysis.table.limits import (
    AXES,
    DEG,
    TABLE_IV,
    AxisLimits,
    Check,
    TableLimits,
    TableModelError,
    TiltLimits,
    half_angle,
)
from analysis.table.link import RANGES as LINK_KEYS
from analysis.table.link import LinkSettings
from analysis.table.network import NetworkSettings, read_network
from analysis.table.sensors import SensorSheets, read_sensors
from analysis.table.toml_check import TomlChecker, TomlFileError, read_toml, shown
from analysis.table.toml_lines import KeyPath


class TableConfiguration(NamedTuple):
    """What a rig configuration gives a `analysis.table.model.TableModel`: its fields, in their order."""

    limits: TableLimits
    geometry: HexapodGeometry
    controller_rate: float
    """The rate setpoints are played at [Hz]."""
    dynamics: TableDynamics
    link: LinkSettings
    drives: DriveSettings
    sensors: SensorSheets
    detectors: LimitDetectors
    network: NetworkSettings = NetworkSettings()
    """This machine's TLS identity (``[network]``): not written by :func:`configuration_dict`."""


def configuration_dict(configuration: TableConfiguration) -> dict[str, Any]:
    """The configuration as plain JSON types in the TOML file's layout, SI keys, explicit joints (``[dynamics]``
    and ``[controller]`` only when they differ from the defaults)."""
    g, lim = configuration.geometry, configuration.limits
    limits: dict[str, Any] = {
        name: {"displacement_m": lim.axis(name).displacement, "velocity_m_s": lim.axis(name).velocity,
               "acceleration_m_s2": lim.axis(name).acceleration}
        for name in AXES
    }
    limits["tilt"] = {"angle_rad": lim.tilt.angle, "rate_rad_s": lim.tilt.rate,
                      "acceleration_rad_s2": lim.tilt.acceleration, "jerk_rad_s3": lim.tilt.jerk}
    hexapod = {"base_joints_m": g.base_joints.tolist(), "platform_joints_m": g.platform_joints.tolist(),
               "home_height_m": g.home_height, "leg_min_m": g.leg_min, "leg_max_m": g.leg_max,
               "leg_speed_m_s": g.leg_speed}
    out = {"table": {"controller_rate_hz": configuration.controller_rate}, "limits": limits, "hexapod": hexapod}
    if configuration.dynamics != TableDynamics():
        out["dynamics"] = configuration.dynamics.to_dict()
    if configuration.link != LinkSettings():
        out["controller"] = configuration.link.to_dict()
    if configuration.drives != DriveSettings():
        out["drives"] = configuration.drives.to_dict()
    if configuration.sensors != SensorSheets():
        out["sensors"] = configuration.sensors.to_dict()
    if configuration.detectors != LimitDetectors():
        out["limit_detectors"] = configuration.detectors.to_dict()
    return out


def configuration_from_dict(data: Mapping[str, Any], source: str = "<dict>") -> TableConfiguration:
    """The configuration of a mapping (the TOML file's layout); errors name ``source`` and the key."""
    return _Reader(source, {}).configuration(data)


def read_configuration(path: str | Path) -> TableConfiguration:
    """The configuration of a rig configuration file; Table IV and the default geometry for what it leaves out.

    Only a regular file of at most 1 MiB is read (`analysis.table.toml_check.read_toml`)."""
    source = str(path)
    try:
        data, lines = read_toml(path, "a rig configuration file")
    except TomlFileError as exc:
        if exc.line is None and exc.problem == "no such file":
            raise TableModelError(f"{source}: no such rig configuration file") from None
        where = f"{source}:{exc.line}" if exc.line else source
        raise TableModelError(f"{where}: {exc.problem}") from None
    return _Reader(source, lines).configuration(data)


_Spec = dict[str, tuple[dict[str, float], Check]]  # field -> ({key: factor to SI}, validator)

def _within(low: float, high: float, text: str) -> Check:
    """A validator of the physical range ``[low, high]`` in SI; ``text`` states it for people, with units."""

    def check(value: float, given: object) -> str | None:
        return None if math.isfinite(value) and low <= value <= high else f"must be {text}, got {shown(given)}"

    return check


#: Physical ranges of the rig configuration's numbers (SI inside; the text as the module docstring states them).
_DISPLACEMENT = _within(0.001, 2.0, "from 0.001 m to 2 m")
_VELOCITY = _within(0.001, 5.0, "from 0.001 m/s to 5 m/s")
_ACCELERATION = _within(0.001 * G, 10.0 * G, "from 0.001 g to 10 g (0.00981 m/s² to 98.1 m/s²)")
_TILT_RANGES = {
    "angle": _within(0.1 * DEG, 45 * DEG, "from 0.1° to 45° (0.001745 rad to 0.7854 rad)"),
    "rate": _within(0.01 * DEG, 90 * DEG, "from 0.01°/s to 90°/s (0.0001745 rad/s to 1.571 rad/s)"),
    "acceleration": _within(0.01 * DEG, 360 * DEG, "from 0.01°/s² to 360°/s² (0.0001745 to 6.283 rad/s²)"),
    "jerk": _within(0.01 * DEG, 3600 * DEG, "from 0.01°/s³ to 3600°/s³ (0.0001745 to 62.83 rad/s³)"),
}
_LENGTH = _within(0.05, 20.0, "from 0.05 m to 20 m")
MAX_JOINT_M = 20.0
"""Largest |coordinate| of an explicit joint [m]."""

_AXIS_SPEC: _Spec = {
    "displacement": ({"displacement_m": 1.0}, _DISPLACEMENT),
    "velocity": ({"velocity_m_s": 1.0}, _VELOCITY),
    "acceleration": ({"acceleration_g": G, "acceleration_m_s2": 1.0}, _ACCELERATION),
}
_TILT_SPEC: _Spec = {
    name: ({f"{name}_deg{suffix}": DEG, f"{name}_rad{suffix}": 1.0}, _TILT_RANGES[name])
    for name, suffix in (("angle", ""), ("rate", "_s"), ("acceleration", "_s2"), ("jerk", "_s3"))
}
_TABLE_SPEC: _Spec = {"controller_rate": ({"controller_rate_hz": 1.0}, _within(10.0, 5000.0, "from 10 Hz to 5000 Hz"))}
_LEG_SPEC: _Spec = {
    "home_height": ({"home_height_m": 1.0}, _LENGTH),
    "leg_min": ({"leg_min_m": 1.0}, _LENGTH),
    "leg_max": ({"leg_max_m": 1.0}, _LENGTH),
    "leg_speed": ({"leg_speed_m_s": 1.0}, _VELOCITY),
}
_LAYOUT_SPEC: _Spec = {
    "base_radius": ({"base_radius_m": 1.0}, _LENGTH),
    "platform_radius": ({"platform_radius_m": 1.0}, _LENGTH),
    "base_half_angle": ({"base_half_angle_deg": DEG, "base_half_angle_rad": 1.0}, half_angle),
    "platform_half_angle": ({"platform_half_angle_deg": DEG, "platform_half_angle_rad": 1.0}, half_angle),
    "platform_joint_depth": ({"platform_joint_depth_m": 1.0}, _within(0.0, 2.0, "from 0 m to 2 m")),
}
#: Physical ranges of the ``[dynamics]`` keys (low, high, as stated), checked before `TableDynamics` is built.
DYNAMICS_RANGES: dict[str, tuple[float, float, str]] = {
    "bore_m": (0.005, 1.0, "from 0.005 m to 1 m"),
    "bulk_modulus_pa": (1e7, 1e10, "from 1e7 Pa to 1e10 Pa"),
    "line_volume_m3": (0.0, 1.0, "from 0 m³ to 1 m³"),
    "plate_mass_kg": (1.0, 1e5, "from 1 kg to 1e5 kg"),
    "piston_mass_kg": (0.1, 1e4, "from 0.1 kg to 1e4 kg"),
    "damping_ratio": (0.001, 0.999, "from 0.001 to 0.999 (< 1: an underdamped oil column)"),
    "valve_bandwidth_hz": (1.0, 1e4, "from 1 Hz to 1e4 Hz"),
    "loop_gain_per_s": (0.01, 1000.0, "from 0.01 /s to 1000 /s"),
    "velocity_feedforward": (0.0, 1.5, "from 0 to 1.5"),
}
_JOINT_KEYS = ("base_joints_m", "platform_joints_m")
DYNAMICS_KEYS = tuple(TableDynamics().to_dict())
_OPTIONAL_LAYOUT = {"platform_joint_depth": 0.0}


def _keys(spec: _Spec) -> list[str]:
    return [key for keys, _ in spec.values() for key in keys]


class _Reader(TomlChecker):
    """Reads a configuration mapping; ``lines`` (`key_lines` of the TOML text, empty without one) give the line
    numbers of keys."""

    def __init__(self, source: str, lines: Mapping[KeyPath, int]) -> None:
        super().__init__(source, lines)

    def error(self, path: KeyPath, problem: str) -> TableModelError:
        line = self.line(path)
        where = f"{self.source}:{line}" if line else self.source
        return TableModelError(f"{where}: {'.'.join(map(str, path))}: {problem}" if path else f"{where}: {problem}")

    def configuration(self, data: Mapping[str, Any]) -> TableConfiguration:
        top = self.table(data, (), ("table", "limits", "hexapod", "dynamics", "controller", "drives", "sensors",
                                       "limit_detectors", "network"))
        table = self.quantities(self.table(top.get("table", {}), ("table",), _keys(_TABLE_SPEC)), ("table",),
                                _TABLE_SPEC, {"controller_rate": 1000.0})
        limits = self.table(top.get("limits", {}), ("limits",), (*AXES, "tilt"))
        axes = {}
        for name in AXES:
            path = ("limits", name)
            values = self.quantities(self.table(limits.get(name, {}), path, _keys(_AXIS_SPEC)), path, _AXIS_SPEC,
                                     vars(TABLE_IV.axis(name)))
            axes[name] = AxisLimits(**values)
        tilt = self.quantities(self.table(limits.get("tilt", {}), ("limits", "tilt"), _keys(_TILT_SPEC)),
                               ("limits", "tilt"), _TILT_SPEC, vars(TABLE_IV.tilt))
        geometry = self.geometry(top["hexapod"]) if "hexapod" in top else HexapodGeometry.default()
        link = self.link(top.get("controller", {}))
        return TableConfiguration(limits=TableLimits(**axes, tilt=TiltLimits(**tilt)), geometry=geometry,
                                  controller_rate=table["controller_rate"],
                                  dynamics=self.dynamics(top.get("dynamics", {})),
                                  link=link,
                                  drives=read_drives(self, top.get("drives")),
                                  sensors=read_sensors(self, top.get("sensors")),
                                  detectors=read_limit_detectors(self, top.get("limit_detectors"),
                                                                 link_timeout_s=link.link_timeout_s),
                                  network=read_network(self, top.get("network")))

    def link(self, value: Any) -> LinkSettings:
        """The ``[controller]`` section (``analysis.table.link``); errors name its line and key."""
        table = self.table(value, ("controller",), tuple(LINK_KEYS))
        for key in table:
            self.real(table[key], ("controller", key))
        values = {key: float(table[key]) for key in table}
        try:
            return LinkSettings.from_dict(values)
        except ValueError as exc:
            key = str(exc).partition(":")[0]
            raise self.error(("controller", key) if key in table else ("controller",),
                             str(exc).partition(": ")[2]) from None

    def dynamics(self, value: Any) -> TableDynamics:
        """The ``[dynamics]`` section (``analysis.table.dynamics``); errors name its line and key."""
        table = self.table(value, ("dynamics",), tuple(DYNAMICS_KEYS))
        for key, given in table.items():
            if key in DYNAMICS_RANGES:
                low, high, text = DYNAMICS_RANGES[key]
                self.ranged(given, ("dynamics", key), low, high, f"a number {text}")
        try:
            return TableDynamics.from_dict(dict(table))
        except ValueError as exc:
            key = str(exc).partition(":")[0]
            raise self.error(("dynamics", key) if key in table else ("dynamics",),
                             str(exc).partition(": ")[2]) from None

    def quantities(self, table: Mapping[str, Any], path: tuple[str, ...], spec: _Spec,
                   defaults: Mapping[str, float] | None) -> dict[str, float]:
        """The SI values of ``spec``'s fields; a missing field takes ``defaults`` (None: required)."""
        values, missing = {}, []
        for name, (keys, check) in spec.items():
            given = [key for key in keys if key in table]
            if len(given) > 1:
                raise self.error((*path, given[1]), f"give either {given[0]} or {given[1]}, not both")
            if not given:
                if defaults is None or name not in defaults:
                    missing.append(" or ".join(keys))
                else:
                    values[name] = defaults[name]
                continue
            raw = self.real(table[given[0]], (*path, given[0]))
            problem = check(raw * keys[given[0]], raw)
            if problem:
                raise self.error((*path, given[0]), problem)
            values[name] = raw * keys[given[0]]
        if missing:
            raise self.error(path, f"missing {', '.join(missing)}")
        return values

    def geometry(self, value: Any) -> HexapodGeometry:
        path = ("hexapod",)
        table = self.table(value, path, (*_keys(_LAYOUT_SPEC), *_JOINT_KEYS, *_keys(_LEG_SPEC)))
        legs = self.quantities(table, path, _LEG_SPEC, None)
        explicit = [key for key in _JOINT_KEYS if key in table]
        if explicit:
            if any(key in table for key in _keys(_LAYOUT_SPEC)):
                raise self.error((*path, explicit[0]), "give either the symmetric layout or explicit joints, not both")
            joints = {key: self.joints(table, (*path, key)) for key in _JOINT_KEYS}
            base, platform = joints["base_joints_m"], joints["platform_joints_m"]
        else:
            base, platform = symmetric_joints(**self.quantities(table, path, _LAYOUT_SPEC, _OPTIONAL_LAYOUT))
        problem = geometry_problem(base, platform, legs["home_height"], legs["leg_min"], legs["leg_max"])
        if problem:
            key = {"leg_max": "leg_max_m", "home_height": "home_height_m"}.get(problem[0], "platform_joints_m")
            raise self.error((*path, key) if key in table else path, problem[1])
        return HexapodGeometry(base, platform, **legs)

    def joints(self, table: Mapping[str, Any], path: tuple[str, ...]) -> np.ndarray:
        if path[-1] not in table:
            raise self.error(path[:-1], f"missing {path[-1]}")
        rows = table[path[-1]]
        if not isinstance(rows, list) or len(rows) != 6:
            raise self.error(path, f"expected 6 joints [[x, y, z], ...] in metres, got {shown(rows)}")
        for k, row in enumerate(rows, start=1):
            if not isinstance(row, list) or len(row) != 3:
                raise self.error(path, f"joint {k}: expected [x, y, z] in metres, got {shown(row)}")
            for coordinate in row:
                if not abs(self.real(coordinate, path)) <= MAX_JOINT_M:
                    raise self.error(path, f"joint {k}: coordinates must be finite and within ±{MAX_JOINT_M:g} m, "
                                           f"got {shown(row)}")
        return np.array(rows, dtype=float)
