"""The shake table: Table IV's motion limits, the hexapod's geometry and its kinematics.

This is the one table model of the project: the drive preparation (``rig``), the controller adapters
(``drivers``) and the emulator (``sim_table``) all import it (docs/architecture.md §1).

Frames and units (docs/architecture.md §2). SI inside: m, s, rad, m/s². The base (world) frame has x = surge,
y = sway (lateral, to the left of +x), z = heave, **z up**, right-handed. A pose is a float array
``(..., 6)``: ``surge, sway, heave`` [m], the displacement of the platform frame from its home pose, and
``roll, pitch, yaw`` [rad], its orientation ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (intrinsic Z-Y'-X'');
this is the column order of the session file's ``commanded`` dataset after its time column. The platform
frame's origin is the centre of the plate's top surface; at home it sits ``home_height`` above the base
frame's origin with the axes parallel to the base frame's.

The plate tilt β > 0 of the study is **pitch = +β**: ``Ry(β)`` takes the plate's +x end down
(``Ry(β) @ [1, 0, 0] = [cos β, 0, −sin β]``), so the plate's +x points downhill and the desired overturn
direction +1 (towards the low side) is towards +x.

Legs are numbered 1..6 in messages (index 0..5 in arrays); leg k joins ``base_joints[k]`` (base frame)
to ``platform_joints[k]`` (platform frame), and its length is the joint-to-joint distance.

The rig configuration file (TOML; every section and every key of ``[table]`` and ``[limits.*]`` may be
left out, which keeps Table IV and the default geometry). Every number has a physical range, given beside
its key; a value outside it is refused with the range (``FILE:LINE: key: must be from … to …, got …``)::

    [table]
    controller_rate_hz = 1000          # the rate setpoints are played at; 10 … 5000 Hz

    [limits.surge]                     # also [limits.lateral] and [limits.heave]; read as ±
    displacement_m = 0.25              # 0.001 … 2 m
    velocity_m_s = 0.5                 # 0.001 … 5 m/s
    acceleration_g = 0.6               # 0.001 … 10 g, or acceleration_m_s2 (0.00981 … 98.1 m/s²)

    [limits.tilt]                      # each also in rad: angle_rad, rate_rad_s, ...
    angle_deg = 10                     # largest |roll|, |pitch|; 0.1 … 45°
    rate_deg_s = 2                     # 0.01 … 90 °/s
    acceleration_deg_s2 = 2            # 0.01 … 360 °/s²
    jerk_deg_s3 = 4                    # 0.01 … 3600 °/s³

    [hexapod]                          # either the symmetric 6-6 layout (HexapodGeometry.symmetric) ...
    base_radius_m = 1.6                # 0.05 … 20 m
    platform_radius_m = 1.1            # 0.05 … 20 m
    base_half_angle_deg = 10           # or base_half_angle_rad; in [0, 60) degrees
    platform_half_angle_deg = 10
    platform_joint_depth_m = 0.15      # optional, default 0: joint centres below the plate's top surface; 0 … 2 m
    home_height_m = 2.1                # 0.05 … 20 m
    leg_min_m = 1.6                    # 0.05 … 20 m
    leg_max_m = 2.85                   # 0.05 … 20 m, above leg_min_m
    leg_speed_m_s = 0.9                # 0.001 … 5 m/s
    # ... or explicit joints instead of the five layout keys:
    # base_joints_m = [[x, y, z], ...]       6 rows, base frame, each coordinate within ±20 m
    # platform_joints_m = [[x, y, z], ...]   6 rows, platform frame, each coordinate within ±20 m
    # with home_height_m, leg_min_m, leg_max_m, leg_speed_m_s

    [dynamics]                         # the legs' servo-hydraulics (analysis/table/dynamics.py, docs/table-dynamics.md)
    bore_m = 0.04                      # 0.005 … 1 m
    bulk_modulus_pa = 1.0e9            # 1e7 … 1e10 Pa
    line_volume_m3 = 0.002             # 0 … 1 m³
    plate_mass_kg = 1500               # 1 … 1e5 kg
    piston_mass_kg = 30                # 0.1 … 1e4 kg
    damping_ratio = 0.3                # 0.001 … 0.999
    valve_bandwidth_hz = 100           # 1 … 1e4 Hz
    loop_gain_per_s = 12               # 0.01 … 1000 /s
    velocity_feedforward = 1.0         # 0 … 1.5

    [controller]                       # the host link (analysis/table/link.py): every key may be left out
    lead_s = 1.0                       # setpoints sent this far ahead
    buffer_s = 4.0                     # the controller's setpoint buffer
    watchdog_s = 1.0                   # no host heartbeat (or chunk while streaming) this long: controlled stop
    link_timeout_s = 0.5               # no status this long: the host declares the link lost

Only a regular file of at most 1 MiB is read (a FIFO, a device or a symlink to one is refused unread).
Errors in a file raise :class:`TableModelError` with a message ``FILE:LINE: dotted.key: problem``.
:meth:`TableModel.to_dict` writes the same layout in SI keys (``acceleration_m_s2``, ``angle_rad``, explicit
joints), so that ``from_dict(to_dict())`` gives back an equal model exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from analysis.body import G
from analysis.errors import AnalysisInputError
from analysis.table.drives import DriveSettings, read_drives
from analysis.table.dynamics import TableDynamics
from analysis.table.link import RANGES as LINK_KEYS
from analysis.table.link import LinkSettings
from analysis.table.toml_check import TomlChecker, TomlFileError, is_number, read_toml, shown
from analysis.table.toml_lines import KeyPath
from analysis.table.toml_lines import suggest as _suggest

_DEG = math.pi / 180.0
"""One degree [rad]; every degree value of this module (defaults and files) is converted with it."""

AXES = ("surge", "lateral", "heave")
"""The translational axes of Table IV, in pose column order 0, 1, 2."""

TILTS = ("roll", "pitch")
"""The limited rotations, in pose column order 3, 4."""


class TableModelError(AnalysisInputError):
    """A bad table configuration; from a file the message starts with ``FILE:LINE: key:``."""


_Check = Callable[[float, float], str | None]
"""A validator: (value in SI, value as given) → what is wrong, or None."""


def _positive(value: float, shown: float) -> str | None:
    return None if math.isfinite(value) and value > 0 else f"must be a finite number > 0, got {shown!r}"


def _non_negative(value: float, shown: float) -> str | None:
    return None if math.isfinite(value) and value >= 0 else f"must be a finite number >= 0, got {shown!r}"


def _half_angle(value: float, shown: float) -> str | None:
    ok = math.isfinite(value) and 0 <= value < math.pi / 3
    return None if ok else f"must be at least 0 and below 60° (π/3 rad), got {shown!r}"


def _problem(value: object, check: _Check) -> str | None:
    """What is wrong with a number given in SI, or None."""
    return check(float(value), value) if is_number(value) else f"expected a number, got {value!r}"


def _check_fields(owner: object, check: _Check, names: tuple[str, ...]) -> None:
    """Validate the named attributes of a frozen dataclass and store them as floats."""
    for name in names:
        value = getattr(owner, name)
        problem = _problem(value, check)
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
        _check_fields(self, _positive, ("displacement", "velocity", "acceleration"))


@dataclass(frozen=True)
class TiltLimits:
    """The limits of roll and pitch: |angle| [rad], rate [rad/s], acceleration [rad/s²], jerk [rad/s³].

    Rate, acceleration and jerk bound the static tilt ramp to β and back; Table IV has no rotations,
    the defaults (10°, 2°/s, 2°/s², 4°/s³) are the rig's.
    """

    angle: float = 10 * _DEG
    rate: float = 2 * _DEG
    acceleration: float = 2 * _DEG
    jerk: float = 4 * _DEG

    def __post_init__(self) -> None:
        _check_fields(self, _positive, ("angle", "rate", "acceleration", "jerk"))


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


def rotation_matrices(poses: np.ndarray) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` of each pose ``(..., 6)`` → ``(..., 3, 3)`` (platform → base)."""
    poses = np.asarray(poses, dtype=float)
    cos, sin = np.cos(poses[..., 3:6]), np.sin(poses[..., 3:6])
    cr, cp, cy = cos[..., 0], cos[..., 1], cos[..., 2]
    sr, sp, sy = sin[..., 0], sin[..., 1], sin[..., 2]
    R = np.empty((*poses.shape[:-1], 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sp, cp * sr, cp * cr
    return R


class _Legs(NamedTuple):
    """The legs at poses ``(..., 6)``: vectors base joint → platform joint ``d`` ``(..., 6, 3)`` [m], the
    rotated platform joints ``rq = R q`` ``(..., 6, 3)`` [m] and the rotations ``R`` ``(..., 3, 3)``."""

    poses: np.ndarray
    d: np.ndarray
    rq: np.ndarray
    R: np.ndarray

    def lengths(self) -> np.ndarray:
        return np.sqrt(np.einsum("...i,...i->...", self.d, self.d))

    def jacobian(self) -> np.ndarray:
        """d(leg lengths)/d(pose) ``(..., 6, 6)``.

        Translation columns: the unit leg vector u. Rotation columns: ``dL/dθ = u · (ω_θ × R q) =
        (R q × u) · ω_θ`` where ω_θ is the angular velocity per unit rate of that Euler angle: roll →
        ``R [1, 0, 0]``, pitch → ``Rz(yaw) [0, 1, 0]``, yaw → ``[0, 0, 1]``.
        """
        u = self.d / self.lengths()[..., None]
        yaw = self.poses[..., 5]
        zeros, ones = np.zeros_like(yaw), np.ones_like(yaw)
        omega = np.stack([self.R[..., :, 0], np.stack([-np.sin(yaw), np.cos(yaw), zeros], -1),
                          np.stack([zeros, zeros, ones], -1)], axis=-2)  # (..., 3 angles, 3)
        return np.concatenate([u, np.einsum("...kj,...aj->...ka", np.cross(self.rq, u), omega)], axis=-1)

    def rates(self, pose_rates: np.ndarray, lengths: np.ndarray | None = None) -> np.ndarray:
        """d(leg lengths)/dt ``(..., 6)`` [m/s] for pose rates ``(..., 6)``: ``u · (v + ω × R q)``.

        The same numbers as ``jacobian() @ pose_rates`` without building the Jacobian (a long trajectory
        is checked in one pass). ω is the platform's angular velocity from the Euler angle rates (see
        `jacobian`).
        """
        lengths = self.lengths() if lengths is None else lengths
        yaw = self.poses[..., 5]
        omega = pose_rates[..., 3, None] * self.R[..., :, 0]
        omega[..., 0] -= pose_rates[..., 4] * np.sin(yaw)
        omega[..., 1] += pose_rates[..., 4] * np.cos(yaw)
        omega[..., 2] += pose_rates[..., 5]
        joint_velocity = np.cross(omega[..., None, :], self.rq)
        joint_velocity += pose_rates[..., None, :3]
        return np.einsum("...ki,...ki->...k", self.d, joint_velocity) / lengths


def _legs(base: np.ndarray, platform: np.ndarray, home_height: float, poses: np.ndarray) -> _Legs:
    """The legs of a hexapod at poses ``(..., 6)``."""
    R = rotation_matrices(poses)
    # R q for every pose and joint as three broadcast multiply-adds: no BLAS call, whose threads stall
    # when the machine's cores are busy (seen: 1 ms → 120 ms for 100k poses)
    columns = R[..., None, :, :]  # (..., 1, 3, 3)
    rq = columns[..., 0] * platform[:, 0, None] + columns[..., 1] * platform[:, 1, None] \
        + columns[..., 2] * platform[:, 2, None]
    origin = poses[..., :3] + np.array([0.0, 0.0, home_height])
    return _Legs(poses, rq + (origin[..., None, :] - base), rq, R)


def _geometry_problem(base: np.ndarray, platform: np.ndarray, home_height: float, leg_min: float, leg_max: float,
                      ) -> tuple[str, str] | None:
    """The first cross-field problem of a geometry as ``(field, message)``, else None."""
    if leg_min >= leg_max:
        return "leg_max", f"must exceed leg_min ({leg_min!r} m), got {leg_max!r} m"
    legs = _legs(base, platform, home_height, np.zeros(6))
    lengths = legs.lengths()
    outside = np.flatnonzero((lengths < leg_min) | (lengths > leg_max))
    if outside.size:
        k = int(outside[0])
        return "home_height", (f"the home pose is outside the stroke: leg {k + 1} length {lengths[k]:.4f} m "
                               f"is not in [{leg_min:.4f}, {leg_max:.4f}] m")
    condition = np.linalg.cond(legs.jacobian())
    if not condition < 1e8:
        return "platform_joints", f"the legs are singular at home (Jacobian condition number {condition:.3g})"
    return None


@dataclass(frozen=True, eq=False)
class HexapodGeometry:
    """A 6-6 hexapod: joint centres, home height [m], leg length range [m] and leg speed [m/s].

    ``base_joints`` ``(6, 3)`` are in the base frame, ``platform_joints`` ``(6, 3)`` in the platform frame
    (origin at the centre of the plate's top surface); ``home_height`` is the height of the platform
    frame's origin above the base frame's origin at home. ``leg_min``/``leg_max`` bound each leg's
    joint-to-joint length, ``leg_speed`` its |d length/dt|. The arrays are stored as read-only copies.
    """

    base_joints: np.ndarray
    platform_joints: np.ndarray
    home_height: float
    leg_min: float
    leg_max: float
    leg_speed: float

    def __post_init__(self) -> None:
        for name in ("base_joints", "platform_joints"):
            try:
                joints = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise TableModelError(f"HexapodGeometry.{name}: expected 6 rows [x, y, z] in metres") from None
            if joints.shape != (6, 3) or not np.all(np.isfinite(joints)):
                raise TableModelError(f"HexapodGeometry.{name}: expected 6 finite rows [x, y, z] in metres, "
                                      f"got shape {joints.shape}")
            joints.setflags(write=False)
            object.__setattr__(self, name, joints)
        _check_fields(self, _positive, ("home_height", "leg_min", "leg_max", "leg_speed"))
        problem = _geometry_problem(self.base_joints, self.platform_joints, self.home_height, self.leg_min,
                                    self.leg_max)
        if problem:
            raise TableModelError(f"HexapodGeometry.{problem[0]}: {problem[1]}")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, HexapodGeometry):
            return NotImplemented
        return (np.array_equal(self.base_joints, other.base_joints)
                and np.array_equal(self.platform_joints, other.platform_joints)
                and self._scalars() == other._scalars())

    def __hash__(self) -> int:
        return hash((tuple(self.base_joints.ravel().tolist()), tuple(self.platform_joints.ravel().tolist()),
                     self._scalars()))

    def _scalars(self) -> tuple[float, float, float, float]:
        return self.home_height, self.leg_min, self.leg_max, self.leg_speed

    @classmethod
    def default(cls) -> HexapodGeometry:
        """The rig's hexapod, sized so that Table IV's whole box combined with a 10° tilt is playable.

        Layout (:meth:`symmetric`): base joints on a 1.6 m radius circle, platform joints on a 1.1 m
        radius circle under a ~3 m plate, both in pairs at ±10° (platform pairs rotated by 60°), platform
        joint centres 0.15 m below the plate's top surface, home height 2.1 m (home leg length 2.208 m,
        the legs lean ~28° from vertical).

        Stroke: over the workspace |surge|, |sway| ≤ 0.25 m, |heave| ≤ 0.18 m, |roll|, |pitch| ≤ 10°,
        yaw 0, the legs span 1.6703 … 2.7798 m (the extremes are at corners of that box; found by
        sampling and local optimisation). leg_min = 1.60 m and leg_max = 2.85 m leave 0.070 m at both
        ends; stroke 1.25 m, retracted length 1.60 m = stroke + 0.35 m of cylinder and joints. The 10°
        tilt alone moves a platform joint by 1.1 sin 10° ≈ 0.19 m vertically, which is why the stroke
        is much larger than the ±0.18 m/±0.25 m of the box.

        Speed: a leg's rate is ``u · v + (R q × u) · ω`` (unit leg vector u). For any pose, with
        translational velocities inside Table IV (|v| ≤ √(0.5² + 0.5² + 0.3²) = 0.768 m/s) and roll and
        pitch rates both at 2°/s (|ω| = 0.049 rad/s, |R q| = 1.110 m) it is at most 0.768 + 0.055 =
        0.823 m/s; sampled over the workspace the worst leg needs 0.724 m/s. leg_speed = 0.9 m/s.
        """
        return cls.symmetric(base_radius=1.6, platform_radius=1.1, base_half_angle=10 * _DEG,
                             platform_half_angle=10 * _DEG, home_height=2.1, leg_min=1.6, leg_max=2.85,
                             leg_speed=0.9, platform_joint_depth=0.15)

    @classmethod
    def symmetric(cls, base_radius: float, platform_radius: float, base_half_angle: float,
                  platform_half_angle: float, home_height: float, leg_min: float, leg_max: float, leg_speed: float,
                  *, platform_joint_depth: float = 0.0) -> HexapodGeometry:
        """The classic 6-6 Stewart layout [m, rad].

        Base joints (z = 0) at radius ``base_radius`` and azimuths ``0° ∓ a, 120° ∓ a, 240° ∓ a``
        (``a = base_half_angle``); platform joints at radius ``platform_radius``, ``platform_joint_depth``
        below the plate's top surface (z = −depth in the platform frame), at ``60° ∓ b`` around
        ``−60°, 60°, 180°`` rotated so that leg k joins neighbouring joints: platform azimuths
        ``−60° + b, 60° − b, 60° + b, 180° − b, 180° + b, 300° − b`` (``b = platform_half_angle``).
        Half angles must be in [0, π/3). The layout is symmetric under rotations by 120° about z
        (leg k → k + 2) and under the mirror y → −y (legs 1↔2, 3↔6, 4↔5).
        """
        checks = ((_positive, "base_radius", base_radius), (_positive, "platform_radius", platform_radius),
                  (_half_angle, "base_half_angle", base_half_angle),
                  (_half_angle, "platform_half_angle", platform_half_angle),
                  (_non_negative, "platform_joint_depth", platform_joint_depth))
        for check, name, value in checks:
            problem = _problem(value, check)
            if problem:
                raise TableModelError(f"HexapodGeometry.symmetric: {name}: {problem}")
        base, platform = _symmetric_joints(base_radius, platform_radius, base_half_angle, platform_half_angle,
                                           platform_joint_depth)
        return cls(base, platform, home_height, leg_min, leg_max, leg_speed)


def _symmetric_joints(base_radius: float, platform_radius: float, base_half_angle: float,
                      platform_half_angle: float, platform_joint_depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Base and platform joints ``(6, 3)`` [m] of the layout described in :meth:`HexapodGeometry.symmetric`."""
    a, b = base_half_angle, platform_half_angle
    third = 2 * math.pi / 3
    base_azimuth = np.array([-a, a, third - a, third + a, 2 * third - a, 2 * third + a])
    platform_azimuth = np.array([-third / 2 + b, third / 2 - b, third / 2 + b, 1.5 * third - b, 1.5 * third + b,
                                 2.5 * third - b])
    base = np.stack([base_radius * np.cos(base_azimuth), base_radius * np.sin(base_azimuth), np.zeros(6)], -1)
    platform = np.stack([platform_radius * np.cos(platform_azimuth), platform_radius * np.sin(platform_azimuth),
                         np.full(6, -float(platform_joint_depth))], -1)
    return base, platform


@dataclass(frozen=True)
class Violation:
    """The first place a trajectory leaves the table's limits.

    ``where`` is ``"leg 1"`` … ``"leg 6"``, an axis of :data:`AXES` or ``"roll"``/``"pitch"``; ``quantity``
    one of ``stroke, speed`` (legs), ``displacement, velocity, acceleration`` (axes), ``angle, rate``
    (tilt). ``value`` is the signed offending value [SI]; ``limit`` the magnitude of the ± limit, or for
    ``stroke`` the bound that was crossed (``leg_min`` or ``leg_max``).
    """

    time: float
    where: str
    quantity: str
    value: float
    limit: float

    def message(self) -> str:
        """One sentence for the operator, e.g. ``at t = 12.345 s leg 3 length 1.9123 m exceeds ...``."""
        if self.quantity == "stroke":
            verb = "exceeds" if self.value > self.limit else "is below"
            return (f"at t = {self.time:.3f} s {self.where} length {self.value:.4f} m {verb} the stroke limit "
                    f"{self.limit:.4f} m")
        unit, scale, other_unit = _UNITS[self.quantity]
        if other_unit:
            value = f"{self.value:.4f} {unit} ({self.value * scale:.3f}{other_unit})"
            limit = f"±{self.limit:.4f} {unit} ({self.limit * scale:.3f}{other_unit})"
        else:
            value, limit = f"{self.value:.4f} {unit}", f"±{self.limit:.4f} {unit}"
        return f"at t = {self.time:.3f} s {self.where} {self.quantity} {value} exceeds the limit {limit}"


_UNITS = {  # quantity -> SI unit, factor to a second unit, that unit with its separator ("" for none)
    "speed": ("m/s", 1.0, ""),
    "displacement": ("m", 1.0, ""),
    "velocity": ("m/s", 1.0, ""),
    "acceleration": ("m/s²", 1 / G, " g"),
    "angle": ("rad", 1 / _DEG, "°"),
    "rate": ("rad/s", 1 / _DEG, "°/s"),
}


@dataclass(frozen=True)
class TableModel:
    """Limits, geometry and setpoint rate [Hz] of the table, with its kinematics and trajectory check."""

    limits: TableLimits = TABLE_IV
    geometry: HexapodGeometry = field(default_factory=HexapodGeometry.default)
    controller_rate: float = 1000.0
    dynamics: TableDynamics = field(default_factory=TableDynamics)
    """The legs' servo-hydraulic parameters (``[dynamics]``; used by the emulator's ``--dynamics servo``)."""
    link: LinkSettings = field(default_factory=LinkSettings)
    """The host link's lead, buffer, watchdog and link timeout (``[controller]``, ``analysis.table.link``)."""
    drives: DriveSettings = field(default_factory=DriveSettings)
    """The leg drives' units, node ids, EDS files and options (``[drives]``, ``analysis.table.drives``)."""

    def __post_init__(self) -> None:
        if not isinstance(self.limits, TableLimits) or not isinstance(self.geometry, HexapodGeometry):
            raise TableModelError("TableModel: limits must be a TableLimits and geometry a HexapodGeometry")
        if not isinstance(self.dynamics, TableDynamics):
            raise TableModelError("TableModel: dynamics must be a TableDynamics")
        _check_fields(self, _positive, ("controller_rate",))

    # ----- kinematics -------------------------------------------------------------------------------

    def leg_lengths(self, poses: np.ndarray) -> np.ndarray:
        """Inverse kinematics: joint-to-joint leg lengths [m] ``(..., 6)`` of poses ``(..., 6)``."""
        return self._legs(_pose_array(poses, "poses")).lengths()

    def leg_jacobian(self, poses: np.ndarray) -> np.ndarray:
        """d(leg lengths)/d(pose) ``(..., 6 legs, 6 pose coordinates)`` [m/m, m/rad] at poses ``(..., 6)``."""
        return self._legs(_pose_array(poses, "poses")).jacobian()

    def leg_velocities(self, poses: np.ndarray, pose_rates: np.ndarray) -> np.ndarray:
        """Leg length rates [m/s] ``(..., 6)`` for poses and their time derivatives (Euler angle rates)."""
        rates = _pose_array(pose_rates, "pose_rates")
        poses = _pose_array(poses, "poses")
        poses, rates = np.broadcast_arrays(poses, rates)
        return self._legs(poses).rates(rates)

    def pose_from_leg_lengths(self, lengths: np.ndarray, guess: np.ndarray | None = None, *, tol: float = 1e-12,
                              max_iter: int = 50) -> np.ndarray:
        """Forward kinematics: the poses ``(..., 6)`` with leg lengths ``(..., 6)`` [m].

        Newton's method on the six IK residuals with the analytic Jacobian, from ``guess`` (default: home),
        until every leg-length residual is ≤ ``tol`` [m]. The hexapod has several assembly modes; the
        one found is the one Newton reaches from the guess (from home: the one the table runs in).
        Raises :class:`TableModelError` when it does not converge.
        """
        target = _pose_array(lengths, "lengths")
        if np.any(target <= 0):
            raise AnalysisInputError("pose_from_leg_lengths: leg lengths must be > 0 m")
        x = np.zeros_like(target) if guess is None else np.array(np.broadcast_to(guess, target.shape), dtype=float)
        worst = math.inf
        for iteration in range(max_iter + 1):
            legs = self._legs(x)
            residual = legs.lengths() - target
            worst = float(np.max(np.abs(residual), initial=0.0))
            if worst <= tol:
                return x
            if iteration == max_iter or not math.isfinite(worst):
                break
            try:
                x = x - np.linalg.solve(legs.jacobian(), residual[..., None])[..., 0]
            except np.linalg.LinAlgError:
                raise TableModelError(f"forward kinematics: singular leg Jacobian after {iteration} Newton "
                                      f"iterations (largest leg-length residual {worst:.3e} m)") from None
        raise TableModelError(f"forward kinematics did not converge in {max_iter} Newton iterations: largest "
                              f"leg-length residual {worst:.3e} m (tolerance {tol:.1e} m)")

    def _legs(self, poses: np.ndarray) -> _Legs:
        g = self.geometry
        return _legs(g.base_joints, g.platform_joints, g.home_height, poses)

    # ----- limits -----------------------------------------------------------------------------------

    def check_trajectory(self, t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None = None,
                         accelerations: np.ndarray | None = None, *, rtol: float = 1e-9) -> Violation | None:
        """The first sample of a trajectory that leaves the table's limits, or None if it stays inside.

        ``t`` [s] ``(N,)`` strictly increasing, ``poses`` ``(N, 6)``; ``velocities`` and ``accelerations``
        ``(N, 6)`` (pose derivatives, Euler angle rates) when known, else ``np.gradient`` of poses and
        velocities over ``t``. Checked per sample: each leg's IK length within [leg_min, leg_max] and speed
        (``leg_velocities`` when velocities are given, else the gradient of the lengths) within leg_speed;
        each translational axis's displacement, velocity and acceleration; |roll|, |pitch| within the tilt
        angle and their rates within the tilt rate. A value counts as a violation only beyond
        ``limit (1 + rtol)``. Ties at one sample: legs before axes before tilts, then by index, then in the
        order just listed.
        """
        return self._first_breach(t, poses, velocities, accelerations, _AXIS_QUANTITIES, rtol)

    def check_command(self, t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None = None,
                      accelerations: np.ndarray | None = None, *, rtol: float = 1e-9) -> Violation | None:
        """The first sample of a *command* (the setpoints a drive streams) that leaves what the table enforces on
        its commands, or None: as :meth:`check_trajectory` but of the translational axes only the displacement.

        The controller clips a setpoint to the per-axis displacement envelope and the tilt angle, each leg's
        command to its stroke, and each leg's servo-valve saturates at the leg speed (``sim_table.dynamics``:
        |w| ≤ leg_speed, the feed-forward of the command's leg rate): those a command must respect to be played
        as written. Table IV's velocity and acceleration are the *plate's* (the response's): a compensated drive
        asks more acceleration than it gets where the table attenuates, and nothing in the table limits a
        command's acceleration — its response is what must stay within Table IV
        (``rig.compensation.safety.check_prediction``). Arguments and result as :meth:`check_trajectory`.
        """
        return self._first_breach(t, poses, velocities, accelerations, ("displacement",), rtol)

    def _first_breach(self, t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None,
                      accelerations: np.ndarray | None, quantities: tuple[str, ...], rtol: float
                      ) -> Violation | None:
        """:meth:`check_trajectory` checking of the translational axes only ``quantities`` (of
        :data:`_AXIS_QUANTITIES`; the others unbounded)."""
        t, poses, velocities, accelerations = _trajectory(t, poses, velocities, accelerations)
        leg_rates_from_gradient = velocities is None
        if velocities is None:
            velocities = np.gradient(poses, t, axis=0)
        if accelerations is None:
            accelerations = np.gradient(velocities, t, axis=0)
        g, lim = self.geometry, self.limits
        axis_bounds = np.array([[getattr(lim.axis(name), q) if q in quantities else math.inf
                                 for q in _AXIS_QUANTITIES] for name in AXES])
        leg_rates = None
        if leg_rates_from_gradient:
            leg_rates = np.gradient(self.leg_lengths(poses), t, axis=0)
        row, column, value, above = _first_violation(
            poses, velocities, accelerations, leg_rates if leg_rates is not None else np.empty((0, 6)),
            g.base_joints, g.platform_joints, g.home_height, g.leg_min, g.leg_max, g.leg_speed, axis_bounds,
            lim.tilt.angle, lim.tilt.rate, rtol,
        )
        if row < 0:
            return None
        where, quantity, low, high = _check_column(column, g, lim)
        limit = high if above else (low if quantity == "stroke" else -low)
        return Violation(time=float(t[row]), where=where, quantity=quantity, value=float(value), limit=float(limit))

    # ----- configuration ----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain JSON types in the TOML file's layout, SI keys, explicit joints."""
        g, lim = self.geometry, self.limits
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
        out = {"table": {"controller_rate_hz": self.controller_rate}, "limits": limits, "hexapod": hexapod}
        if self.dynamics != TableDynamics():
            out["dynamics"] = self.dynamics.to_dict()
        if self.link != LinkSettings():
            out["controller"] = self.link.to_dict()
        if self.drives != DriveSettings():
            out["drives"] = self.drives.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> TableModel:
        """The model of a configuration mapping (the TOML file's layout); errors name ``source`` and the key."""
        return _Reader(source, {}).model(data)

    @classmethod
    def from_toml(cls, path: str | Path) -> TableModel:
        """The model of a rig configuration file; Table IV and the default geometry for what it leaves out.

        Only a regular file of at most 1 MiB is read (`analysis.table.toml_check.read_toml`)."""
        source = str(path)
        try:
            data, lines = read_toml(path, "a rig configuration file")
        except TomlFileError as exc:
            if exc.line is None and exc.problem == "no such file":
                raise TableModelError(f"{source}: no such rig configuration file") from None
            where = f"{source}:{exc.line}" if exc.line else source
            raise TableModelError(f"{where}: {exc.problem}") from None
        return _Reader(source, lines).model(data)


# ----- input arrays -------------------------------------------------------------------------------------


def _pose_array(values: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    if array.ndim == 0 or array.shape[-1] != 6:
        raise AnalysisInputError(f"{name}: expected an array of shape (..., 6), got shape {array.shape}")
    return array


def _trajectory(t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None, accelerations: np.ndarray | None,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Validated ``check_trajectory`` inputs as float arrays (velocities/accelerations may stay None)."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise AnalysisInputError(f"check_trajectory: t must be a 1-D array of at least 2 times [s], "
                                 f"got shape {t.shape}")
    arrays = {"poses": poses, "velocities": velocities, "accelerations": accelerations}
    for name, values in arrays.items():
        if values is None:
            continue
        array = np.asarray(values, dtype=float)
        if array.shape != (t.size, 6):
            raise AnalysisInputError(f"check_trajectory: {name} must have shape ({t.size}, 6) to match t, "
                                     f"got {array.shape}")
        arrays[name] = array
    for name, array in {"t": t, **arrays}.items():
        if array is not None and not np.all(np.isfinite(array)):
            row = int(np.flatnonzero(~np.isfinite(array).reshape(t.size, -1).all(axis=1))[0])
            raise AnalysisInputError(f"check_trajectory: {name} has a non-finite value at sample {row}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise AnalysisInputError(f"check_trajectory: t must be strictly increasing, but t[{i + 1}] = "
                                 f"{float(t[i + 1])!r} s follows t[{i}] = {float(t[i])!r} s")
    return t, arrays["poses"], arrays["velocities"], arrays["accelerations"]


# ----- the trajectory check's compiled kernel -----------------------------------------------------------

#: Checks per sample, in the order ties are broken: legs 1–6 (stroke, speed), then surge, lateral, heave
#: (displacement, velocity, acceleration), then roll and pitch (angle, rate).
_AXIS_QUANTITIES = ("displacement", "velocity", "acceleration")


def _check_column(column: int, g: HexapodGeometry, lim: TableLimits) -> tuple[str, str, float, float]:
    """Name, quantity and (low, high) bounds of one check column of `_first_violation`."""
    if column < 12:
        leg, kind = divmod(column, 2)
        if kind == 0:
            return f"leg {leg + 1}", "stroke", g.leg_min, g.leg_max
        return f"leg {leg + 1}", "speed", -g.leg_speed, g.leg_speed
    if column < 21:
        axis, kind = divmod(column - 12, 3)
        bound = getattr(lim.axis(AXES[axis]), _AXIS_QUANTITIES[kind])
        return AXES[axis], _AXIS_QUANTITIES[kind], -bound, bound
    tilt, kind = divmod(column - 21, 2)
    bound = lim.tilt.angle if kind == 0 else lim.tilt.rate
    return TILTS[tilt], ("angle", "rate")[kind], -bound, bound


@njit(cache=True)
def _outside(value: float, low: float, high: float, rtol: float) -> int:
    """+1 above ``high (1 + rtol)``, -1 below ``low`` by more than ``rtol |low|``, else 0."""
    if value > high + rtol * abs(high):
        return 1
    if value < low - rtol * abs(low):
        return -1
    return 0


@njit(cache=True)
def _first_violation(poses, velocities, accelerations, leg_rates, base, platform, home_height, leg_min, leg_max,
                     leg_speed, axis_bounds, tilt_angle, tilt_rate, rtol):  # pragma: no cover - compiled
    """(row, column, value, above) of the first sample outside a limit, or (-1, -1, 0, False).

    One pass over the samples with an exit at the first violation; the rotation is recomputed only when
    the angles change (a drive holds its tilt for most of its length). Leg speeds are ``u · (v + ω × R q)``
    (`_Legs.rates`) unless ``leg_rates`` (N, 6) is given.
    """
    n = poses.shape[0]
    R = np.empty((3, 3))
    last = np.full(3, np.nan)
    rq = np.empty(3)
    for i in range(n):
        roll, pitch, yaw = poses[i, 3], poses[i, 4], poses[i, 5]
        if roll != last[0] or pitch != last[1] or yaw != last[2]:
            cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
            R[0, 0], R[0, 1], R[0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
            R[1, 0], R[1, 1], R[1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
            R[2, 0], R[2, 1], R[2, 2] = -sp, cp * sr, cp * cr
            last[0], last[1], last[2] = roll, pitch, yaw
        # angular velocity from the Euler rates: roll about R[:, 0], pitch about Rz(yaw) y, yaw about z
        roll_rate, pitch_rate, yaw_rate = velocities[i, 3], velocities[i, 4], velocities[i, 5]
        wx = roll_rate * R[0, 0] - pitch_rate * np.sin(yaw)
        wy = roll_rate * R[1, 0] + pitch_rate * np.cos(yaw)
        wz = roll_rate * R[2, 0] + yaw_rate
        for k in range(6):
            for a in range(3):
                rq[a] = R[a, 0] * platform[k, 0] + R[a, 1] * platform[k, 1] + R[a, 2] * platform[k, 2]
            dx = rq[0] + poses[i, 0] - base[k, 0]
            dy = rq[1] + poses[i, 1] - base[k, 1]
            dz = rq[2] + poses[i, 2] + home_height - base[k, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            side = _outside(length, leg_min, leg_max, rtol)
            if side != 0:
                return i, 2 * k, length, side > 0
            if leg_rates.shape[0] > 0:
                rate = leg_rates[i, k]
            else:
                jx = velocities[i, 0] + wy * rq[2] - wz * rq[1]
                jy = velocities[i, 1] + wz * rq[0] - wx * rq[2]
                jz = velocities[i, 2] + wx * rq[1] - wy * rq[0]
                rate = (dx * jx + dy * jy + dz * jz) / length
            side = _outside(rate, -leg_speed, leg_speed, rtol)
            if side != 0:
                return i, 2 * k + 1, rate, side > 0
        for a in range(3):
            for q in range(3):
                value = poses[i, a] if q == 0 else (velocities[i, a] if q == 1 else accelerations[i, a])
                side = _outside(value, -axis_bounds[a, q], axis_bounds[a, q], rtol)
                if side != 0:
                    return i, 12 + 3 * a + q, value, side > 0
        for m in range(2):
            for q in range(2):
                value = poses[i, 3 + m] if q == 0 else velocities[i, 3 + m]
                bound = tilt_angle if q == 0 else tilt_rate
                side = _outside(value, -bound, bound, rtol)
                if side != 0:
                    return i, 21 + 2 * m + q, value, side > 0
    return -1, -1, 0.0, False


# ----- configuration files -----------------------------------------------------------------------------

_Spec = dict[str, tuple[dict[str, float], _Check]]  # field -> ({key: factor to SI}, validator)

def _within(low: float, high: float, text: str) -> _Check:
    """A validator of the physical range ``[low, high]`` in SI; ``text`` states it for people, with units."""

    def check(value: float, given: float) -> str | None:
        return None if math.isfinite(value) and low <= value <= high else f"must be {text}, got {shown(given)}"

    return check


#: Physical ranges of the rig configuration's numbers (SI inside; the text as the module docstring states them).
_DISPLACEMENT = _within(0.001, 2.0, "from 0.001 m to 2 m")
_VELOCITY = _within(0.001, 5.0, "from 0.001 m/s to 5 m/s")
_ACCELERATION = _within(0.001 * G, 10.0 * G, "from 0.001 g to 10 g (0.00981 m/s² to 98.1 m/s²)")
_TILT_RANGES = {
    "angle": _within(0.1 * _DEG, 45 * _DEG, "from 0.1° to 45° (0.001745 rad to 0.7854 rad)"),
    "rate": _within(0.01 * _DEG, 90 * _DEG, "from 0.01°/s to 90°/s (0.0001745 rad/s to 1.571 rad/s)"),
    "acceleration": _within(0.01 * _DEG, 360 * _DEG, "from 0.01°/s² to 360°/s² (0.0001745 to 6.283 rad/s²)"),
    "jerk": _within(0.01 * _DEG, 3600 * _DEG, "from 0.01°/s³ to 3600°/s³ (0.0001745 to 62.83 rad/s³)"),
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
    name: ({f"{name}_deg{suffix}": _DEG, f"{name}_rad{suffix}": 1.0}, _TILT_RANGES[name])
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
    "base_half_angle": ({"base_half_angle_deg": _DEG, "base_half_angle_rad": 1.0}, _half_angle),
    "platform_half_angle": ({"platform_half_angle_deg": _DEG, "platform_half_angle_rad": 1.0}, _half_angle),
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

    def model(self, data: Mapping[str, Any]) -> TableModel:
        top = self.table(data, (), ("table", "limits", "hexapod", "dynamics", "controller", "drives"))
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
        return TableModel(limits=TableLimits(**axes, tilt=TiltLimits(**tilt)), geometry=geometry,
                          controller_rate=table["controller_rate"], dynamics=self.dynamics(top.get("dynamics", {})),
                          link=self.link(top.get("controller", {})), drives=read_drives(self, top.get("drives")))

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
            base, platform = _symmetric_joints(**self.quantities(table, path, _LAYOUT_SPEC, _OPTIONAL_LAYOUT))
        problem = _geometry_problem(base, platform, legs["home_height"], legs["leg_min"], legs["leg_max"])
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
