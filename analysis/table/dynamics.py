"""The servo-hydraulic parameters of the table's legs (the rig TOML's ``[dynamics]`` section) and their closed forms.

Each of the six legs is a symmetric double-acting hydraulic cylinder of piston diameter ``bore`` [m] whose stroke is
the hexapod's (``leg_max − leg_min``), fed by a servo-valve and closed by the controller's displacement loop
(``sim_table.dynamics``, ``docs/table-dynamics.md``). The oil in both chambers is a spring: at mid-stroke, with the
total oil volume ``V_t = A·stroke + line_volume`` (both chambers and the lines to the valve) and the effective bulk
modulus β (oil with entrained air and hose compliance), the hydraulic stiffness is ``k_h = 4 β A² / V_t`` and the
oil-column (hydraulic natural) frequency under the moving mass ``m`` is

    ω_h = sqrt(4 β A² / (V_t m))                       (Merritt, *Hydraulic Control Systems*, 1967, §6.3, Eq. 6-28)

— the form ``sqrt(2 β A² / (V m))`` per chamber of volume ``V = V_t/2``: each chamber is a spring ``β A² / V`` and
the two act in parallel. The moving mass per leg is its piston and rod plus a sixth of the plate and specimens
(``plate_mass`` + the bodies standing on it): the legs are treated as six equal, uncoupled columns.

The TOML section (every key optional; the defaults give a 12–13 Hz oil column on the Table IV rig)::

    [dynamics]
    bore_m = 0.04                  # piston diameter
    bulk_modulus_pa = 1.0e9        # effective bulk modulus (oil + hoses + air)
    line_volume_m3 = 0.002         # oil in the lines and valve manifold, both chambers together
    plate_mass_kg = 1500           # the moving plate (without specimens)
    piston_mass_kg = 30            # one leg's moving piston and rod
    damping_ratio = 0.3            # the oil column with the controller's pressure feedback
    valve_bandwidth_hz = 100       # the servo-valve as a first-order lag
    loop_gain_per_s = 12           # the displacement loop's gain K_v (flow per position error)
    velocity_feedforward = 1.0     # share of the reference's velocity fed forward to the valve
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

FIELDS = {
    "bore": "bore_m",
    "bulk_modulus": "bulk_modulus_pa",
    "line_volume": "line_volume_m3",
    "plate_mass": "plate_mass_kg",
    "piston_mass": "piston_mass_kg",
    "damping_ratio": "damping_ratio",
    "valve_bandwidth": "valve_bandwidth_hz",
    "loop_gain": "loop_gain_per_s",
    "velocity_feedforward": "velocity_feedforward",
}
"""Attribute → TOML key (units in the key's name)."""


@dataclass(frozen=True)
class TableDynamics:
    """The legs' servo-hydraulic parameters (module docstring), SI: bore [m], bulk modulus [Pa], line volume [m³],
    plate and piston masses [kg], damping ratio [-], valve bandwidth [Hz], loop gain [1/s], velocity feed-forward
    [-] (0 … 1.5)."""

    bore: float = 0.04
    bulk_modulus: float = 1.0e9
    line_volume: float = 0.002
    plate_mass: float = 1500.0
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
            zero_ok = f.name in ("line_volume", "velocity_feedforward")
            if not (value >= 0 if zero_ok else value > 0):
                raise ValueError(f"{FIELDS[f.name]}: must be {'>= 0' if zero_ok else '> 0'}, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        if self.velocity_feedforward > 1.5:
            raise ValueError(f"velocity_feedforward: must be at most 1.5, got {self.velocity_feedforward!r}")
        if self.damping_ratio >= 1.0:
            raise ValueError(f"damping_ratio: an oil column is underdamped, expected < 1, got {self.damping_ratio!r}")

    @property
    def area(self) -> float:
        """Piston area A = π bore² / 4 [m²]."""
        return math.pi * self.bore**2 / 4.0

    def moving_mass(self, payload: float = 0.0) -> float:
        """Mass one leg moves [kg]: its piston plus a sixth of the plate and of ``payload`` (specimens) [kg]."""
        return self.piston_mass + (self.plate_mass + payload) / 6.0

    def stiffness(self, stroke: float) -> float:
        """Hydraulic stiffness at mid-stroke k_h = 4 β A² / V_t [N/m], V_t = A·``stroke`` + line volume."""
        volume = self.area * stroke + self.line_volume
        return 4.0 * self.bulk_modulus * self.area**2 / volume

    def oil_column_frequency(self, stroke: float, payload: float = 0.0) -> float:
        """ω_h = sqrt(k_h / m) [rad/s] of a leg of ``stroke`` [m] carrying ``payload`` [kg] of specimens."""
        return math.sqrt(self.stiffness(stroke) / self.moving_mass(payload))

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
