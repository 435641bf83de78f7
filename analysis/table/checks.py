"""The trajectory check: the first sample of a trajectory or a command that leaves the table's limits.

One compiled pass (numba) over the samples, with an exit at the first violation: each leg's stroke and speed,
each translational axis's displacement, velocity and acceleration, roll and pitch angle and rate. SI throughout
(m, s, rad); poses as `analysis.table.kinematics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from analysis.body import G
from analysis.compiled_index import njit
from analysis.errors import AnalysisInputError
from analysis.table.kinematics import HexapodGeometry, legs_at
from analysis.table.limits import AXES, DEG, TILTS, TableLimits


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
    "angle": ("rad", 1 / DEG, "°"),
    "rate": ("rad/s", 1 / DEG, "°/s"),
}

#: Checks per sample, in the order ties are broken: legs 1–6 (stroke, speed), then surge, lateral, heave
#: (displacement, velocity, acceleration), then roll and pitch (angle, rate).
AXIS_QUANTITIES = ("displacement", "velocity", "acceleration")


def first_breach(geometry: HexapodGeometry, limits: TableLimits, t: np.ndarray, poses: np.ndarray,
                 velocities: np.ndarray | None, accelerations: np.ndarray | None, quantities: tuple[str, ...],
                 rtol: float) -> Violation | None:
    """`analysis.table.model.TableModel.check_trajectory` checking of the translational axes only ``quantities``
    (of :data:`AXIS_QUANTITIES`; the others unbounded)."""
    t, poses, velocities, accelerations = _trajectory(t, poses, velocities, accelerations)
    leg_rates_from_gradient = velocities is None
    if velocities is None:
        velocities = np.gradient(poses, t, axis=0)
    if accelerations is None:
        accelerations = np.gradient(velocities, t, axis=0)
    g, lim = geometry, limits
    axis_bounds = np.array([[getattr(lim.axis(name), q) if q in quantities else math.inf
                             for q in AXIS_QUANTITIES] for name in AXES])
    leg_rates = None
    if leg_rates_from_gradient:
        leg_rates = np.gradient(legs_at(g.base_joints, g.platform_joints, g.home_height, poses).lengths(), t, axis=0)
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


def _trajectory(t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None, accelerations: np.ndarray | None,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Validated ``check_trajectory`` inputs as float arrays (velocities/accelerations may stay None)."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise AnalysisInputError(f"check_trajectory: t must be a 1-D array of at least 2 times [s], "
                                 f"got shape {t.shape}")
    arrays: dict[str, np.ndarray | None] = {"poses": poses, "velocities": velocities, "accelerations": accelerations}
    for name, values in arrays.items():
        if values is None:
            continue
        array = np.asarray(values, dtype=float)
        if array.shape != (t.size, 6):
            raise AnalysisInputError(f"check_trajectory: {name} must have shape ({t.size}, 6) to match t, "
                                     f"got {array.shape}")
        arrays[name] = array
    for name, given in {"t": t, **arrays}.items():
        if given is not None and not np.all(np.isfinite(given)):
            row = int(np.flatnonzero(~np.isfinite(given).reshape(t.size, -1).all(axis=1))[0])
            raise AnalysisInputError(f"check_trajectory: {name} has a non-finite value at sample {row}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise AnalysisInputError(f"check_trajectory: t must be strictly increasing, but t[{i + 1}] = "
                                 f"{float(t[i + 1])!r} s follows t[{i}] = {float(t[i])!r} s")
    return t, cast(np.ndarray, arrays["poses"]), arrays["velocities"], arrays["accelerations"]  # poses: never None


def _check_column(column: int, g: HexapodGeometry, lim: TableLimits) -> tuple[str, str, float, float]:
    """Name, quantity and (low, high) bounds of one check column of `_first_violation`."""
    if column < 12:
        leg, kind = divmod(column, 2)
        if kind == 0:
            return f"leg {leg + 1}", "stroke", g.leg_min, g.leg_max
        return f"leg {leg + 1}", "speed", -g.leg_speed, g.leg_speed
    if column < 21:
        axis, kind = divmod(column - 12, 3)
        bound = getattr(lim.axis(AXES[axis]), AXIS_QUANTITIES[kind])
        return AXES[axis], AXIS_QUANTITIES[kind], -bound, bound
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
    (`Legs.rates`) unless ``leg_rates`` (N, 6) is given.
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
