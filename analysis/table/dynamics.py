"""The table's servo-hydraulic parameters and rigid plate (the rig TOML's ``[dynamics]`` section), with their closed
forms.

Each leg is a symmetric double-acting cylinder of piston diameter ``bore`` [m] over the hexapod's stroke; its oil
is a spring along the leg's axis of stiffness ``k_h = 4 β A² / V_t`` [N/m] (Merritt 1967, §6.3). The plate is a
rigid body: ``plate_mass`` [kg], principal moments ``plate_inertia_{x,y,z}`` [kg·m²] about its centre of gravity
along the plate's axes, the centre of gravity at ``plate_cg_{x,y,z}`` [m] in the platform frame (origin at the
centre of the plate's top surface, z up: ``plate_cg_z`` ≤ 0); specimens on it are :class:`PlateLoad` rigid masses
at their places. In pose coordinates (surge, sway, heave [m], roll, pitch, yaw [rad]) :func:`rigid_mass_matrix`
gives M(q) and :func:`plate_modes` the six modes of ``Jᵀ K J φ = ω² (M + m_p JᵀJ) φ``.

The model, its equations and sources: docs/table-dynamics.md §The plate on its six legs; the ``[dynamics]`` keys,
their defaults and where they come from: §Parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, Protocol

import numpy as np

from analysis.table.kinematics import HexapodGeometry, rotation_matrices

FIELDS = {
    "bore": "bore_m",
    "bulk_modulus": "bulk_modulus_pa",
    "line_volume": "line_volume_m3",
    "plate_mass": "plate_mass_kg",
    "plate_inertia_x": "plate_inertia_x_kg_m2",
    "plate_inertia_y": "plate_inertia_y_kg_m2",
    "plate_inertia_z": "plate_inertia_z_kg_m2",
    "plate_cg_x": "plate_cg_x_m",
    "plate_cg_y": "plate_cg_y_m",
    "plate_cg_z": "plate_cg_z_m",
    "piston_mass": "piston_mass_kg",
    "damping_ratio": "damping_ratio",
    "valve_bandwidth": "valve_bandwidth_hz",
    "loop_gain": "loop_gain_per_s",
    "velocity_feedforward": "velocity_feedforward",
}
"""Attribute → TOML key (units in the key's name)."""

_SIGNED = frozenset({"plate_cg_x", "plate_cg_y", "plate_cg_z"})
_ZERO_OK = frozenset({"line_volume", "velocity_feedforward"})

CG_REACH = 2.0
"""Largest distance of the plate's centre of gravity from the platform frame's origin [m] (a plate of the paper's
class is ~3 m across: its centre of gravity lies within its half-width of the top surface's centre)."""


@dataclass(frozen=True)
class PlateLoad:
    """A rigid mass carried by the plate (a specimen standing on it): ``mass`` [kg], its centre of gravity
    ``centre`` (x, y, z) [m] in the platform frame, its principal moments of inertia ``inertia`` [kg·m²] about that
    centre along the plate's axes."""

    mass: float
    centre: tuple[float, float, float]
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        values = (self.mass, *self.centre, *self.inertia)
        if len(self.centre) != 3 or len(self.inertia) != 3 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"PlateLoad: expected a finite mass, centre (3) and inertia (3), got {self}")
        if self.mass < 0 or min(self.inertia) < 0:
            raise ValueError(f"PlateLoad: mass and moments of inertia must be >= 0, got {self}")


@dataclass(frozen=True)
class TableDynamics:
    """The legs' servo-hydraulic parameters and the rigid plate (module docstring), SI: bore [m], bulk modulus [Pa],
    line volume [m³], plate mass [kg], the plate's principal moments of inertia about its centre of gravity [kg·m²]
    and that centre in the platform frame [m], piston mass [kg], damping ratio [-], valve bandwidth [Hz], loop gain
    [1/s], velocity feed-forward [-] (0 … 1.5)."""

    bore: float = 0.04
    bulk_modulus: float = 1.0e9
    line_volume: float = 0.002
    plate_mass: float = 1500.0
    plate_inertia_x: float = 1136.25
    plate_inertia_y: float = 1136.25
    plate_inertia_z: float = 2250.0
    plate_cg_x: float = 0.0
    plate_cg_y: float = 0.0
    plate_cg_z: float = -0.15
    piston_mass: float = 30.0
    damping_ratio: float = 0.3
    valve_bandwidth: float = 100.0
    loop_gain: float = 12.0
    velocity_feedforward: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"{FIELDS[f.name]}: expected a finite number, got {value!r}")
            if f.name not in _SIGNED:
                zero_ok = f.name in _ZERO_OK
                if not (value >= 0 if zero_ok else value > 0):
                    raise ValueError(f"{FIELDS[f.name]}: must be {'>= 0' if zero_ok else '> 0'}, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        if self.velocity_feedforward > 1.5:
            raise ValueError(f"velocity_feedforward: must be at most 1.5, got {self.velocity_feedforward!r}")
        if self.damping_ratio >= 1.0:
            raise ValueError(f"damping_ratio: an oil column is underdamped, expected < 1, got {self.damping_ratio!r}")
        moments = {"x": self.plate_inertia_x, "y": self.plate_inertia_y, "z": self.plate_inertia_z}
        for axis, moment in moments.items():
            others = sum(moments.values()) - moment
            if moment > others * (1 + 1e-12):
                raise ValueError(f"plate_inertia_{axis}_kg_m2: a rigid body's principal moment is at most the sum of "
                                 f"the other two ({others!r} kg·m²), got {moment!r}")
        if self.plate_cg_z > 0:
            raise ValueError(f"plate_cg_z_m: the plate lies below its top surface (the platform frame's origin), "
                             f"expected <= 0, got {self.plate_cg_z!r}")
        reach = math.hypot(self.plate_cg_x, self.plate_cg_y, self.plate_cg_z)
        if reach > CG_REACH:
            key = max(("x", "y", "z"), key=lambda a: abs(getattr(self, f"plate_cg_{a}")))
            raise ValueError(f"plate_cg_{key}_m: the centre of gravity is {reach:.3g} m from the top surface's "
                             f"centre, expected within {CG_REACH} m")

    @property
    def area(self) -> float:
        """Piston area A = π bore² / 4 [m²]."""
        return math.pi * self.bore**2 / 4.0

    def stiffness(self, stroke: float) -> float:
        """One leg's hydraulic stiffness at mid-stroke k_h = 4 β A² / V_t [N/m], V_t = A·``stroke`` + line volume."""
        volume = self.area * stroke + self.line_volume
        return 4.0 * self.bulk_modulus * self.area**2 / volume

    def plate(self) -> PlateLoad:
        """The plate itself as a rigid mass."""
        return PlateLoad(self.plate_mass, (self.plate_cg_x, self.plate_cg_y, self.plate_cg_z),
                         (self.plate_inertia_x, self.plate_inertia_y, self.plate_inertia_z))

    def mass_matrix(self, pose: np.ndarray, loads: Sequence[PlateLoad] = ()) -> np.ndarray:
        """The plate's and ``loads``' mass matrix (6, 6) in pose coordinates at ``pose`` (6,) [kg, kg·m, kg·m²]
        (:func:`rigid_mass_matrix`; the legs' pistons are not in it)."""
        return sum((rigid_mass_matrix(load, pose) for load in (self.plate(), *loads)), np.zeros((6, 6)))

    def to_dict(self) -> dict[str, float]:
        """The TOML section's keys and values."""
        return {key: getattr(self, name) for name, key in FIELDS.items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TableDynamics:
        """From the TOML section's keys (missing keys keep their defaults); ValueError naming an unknown key."""
        names = {key: name for name, key in FIELDS.items()}
        unknown = [key for key in data if key not in names]
        if unknown:
            raise ValueError(f"{unknown[0]}: unknown key; expected one of {', '.join(FIELDS.values())}")
        return cls(**{names[key]: value for key, value in data.items()})


def euler_rate_map(pose: np.ndarray) -> np.ndarray:
    """E (3, 3): the plate's angular velocity ω = E · (roll, pitch, yaw rates) [rad/s] at ``pose`` (6,), for
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``: roll turns about R's first column, pitch about Rz(yaw)·ŷ, yaw about ẑ."""
    pitch, yaw = float(pose[4]), float(pose[5])
    cp, sp, cy, sy = math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return np.array([[cy * cp, -sy, 0.0],
                     [sy * cp, cy, 0.0],
                     [-sp, 0.0, 1.0]])


def rigid_mass_matrix(load: PlateLoad, pose: np.ndarray) -> np.ndarray:
    """The mass matrix (6, 6) of a rigid mass fixed to the plate, in pose coordinates at ``pose`` (6,).

    Kinetic energy ``½ m |v + ω × r|² + ½ ωᵀ R I_c Rᵀ ω`` with v the platform origin's velocity, r = R c the
    centre of gravity's offset (base frame) and ω = E · (Euler rates) (:func:`euler_rate_map`):
    ``Tᵀ [[m I, −m S], [m S, R I_c Rᵀ − m S²]] T`` with S = [r]ₓ (S ω = r × ω) and T = diag(I, E).
    """
    pose = np.asarray(pose, dtype=float)
    rotation = rotation_matrices(pose)
    r = rotation @ np.asarray(load.centre, dtype=float)
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    twist = np.zeros((6, 6))
    twist[:3, :3] = load.mass * np.eye(3)
    twist[:3, 3:] = -load.mass * skew
    twist[3:, :3] = load.mass * skew
    twist[3:, 3:] = rotation @ np.diag(load.inertia) @ rotation.T - load.mass * skew @ skew
    transform = np.eye(6)
    transform[3:, 3:] = euler_rate_map(pose)
    return transform.T @ twist @ transform


@dataclass(frozen=True)
class PlateModes:
    """The plate's undamped modes on the six oil columns (valves closed): ``frequencies`` (6,) [Hz], ascending, and
    ``shapes`` (6, 6), column j the pose-coordinate mode shape of mode j, normalised to unit modal mass."""

    frequencies: np.ndarray
    shapes: np.ndarray


class HexapodTable(Protocol):
    """What the plate's modes need of a table (`analysis.table.model.TableModel`): its servo-hydraulic parameters,
    its geometry and its leg Jacobian."""

    @property
    def dynamics(self) -> TableDynamics:
        """The legs' servo-hydraulic parameters and the rigid plate."""

    @property
    def geometry(self) -> HexapodGeometry:
        """The hexapod's joints and leg strokes [m]."""

    def leg_jacobian(self, poses: np.ndarray) -> np.ndarray:
        """d(leg lengths)/d(pose) ``(..., 6, 6)`` [m/m, m/rad] at poses ``(..., 6)``."""


def plate_modes(table: HexapodTable, pose: np.ndarray | None = None, loads: Sequence[PlateLoad] = ()) -> PlateModes:
    """The plate's modes at ``pose`` (6,) (default home) with ``loads`` on it: ``scipy.linalg.eigh`` of
    Jᵀ K J φ = ω² (M + m_p JᵀJ) φ (module docstring)."""
    from scipy.linalg import eigh

    pose = np.zeros(6) if pose is None else np.asarray(pose, dtype=float)
    d, g = table.dynamics, table.geometry
    jacobian = table.leg_jacobian(pose)
    stiffness = d.stiffness(g.leg_max - g.leg_min) * jacobian.T @ jacobian
    mass = d.mass_matrix(pose, loads) + d.piston_mass * jacobian.T @ jacobian
    eigenvalues, shapes = eigh(stiffness, mass)
    return PlateModes(np.sqrt(eigenvalues) / (2.0 * math.pi), shapes)
