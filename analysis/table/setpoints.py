"""What a setpoint must be for the table to play it as written: the one check of a stream's samples that the host
(``drivers``, before it sends them) and the controller (``sim_table``, before it plays them) both make.

A setpoint is a pose ``(surge, sway, heave [m], roll, pitch, yaw [rad])`` as in :mod:`analysis.table.model`. Checked
per sample, in this order (the first problem found is the one reported):

1. **finite**: every coordinate a finite number (NaN, ±inf refused);
2. **envelope**: |surge|, |sway|, |heave| within their Table IV displacements and |roll|, |pitch| within the tilt
   angle (yaw has no limit of its own: the legs' stroke bounds it), each allowed :data:`POSITION_ALLOWANCE` beyond;
3. **stroke**: every leg's length (inverse kinematics, ``TableModel.leg_lengths``) within [leg_min, leg_max],
   allowed :data:`POSITION_ALLOWANCE` beyond;
4. **rate**: from the sample before (the chunk's previous sample, or ``previous`` for the first) to this one, every
   leg's length changes at most ``leg_speed`` and roll and pitch at most the tilt rate, each allowed
   :data:`RATE_ALLOWANCE` beyond; and likewise from the last sample to ``following`` when given.

These are the limits ``TableModel.check_command`` holds a drive to (a prepared or compensated drive passes them); the
allowances absorb what the wire does to a drive that passes it (MAVLink carries float32, CANopen whole µm of leg
length) and the difference between a sampled rate and the continuous one ``check_command`` bounds. Translational
velocities and accelerations are not a command's limits (``TableModel.check_command`` says why).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.table.model import AXES, TILTS, TableModel

POSITION_ALLOWANCE = 1e-5
"""How far beyond a displacement, angle or stroke limit a setpoint may lie [m or rad]: float32 and µm rounding of
a setpoint at the limit stay well inside it (3e-8 m and 5e-7 m)."""

RATE_ALLOWANCE = 0.05
"""How far beyond the leg speed and the tilt rate a step between samples may go, as a share of the limit."""

_COLUMNS = (*AXES, *TILTS, "yaw")


@dataclass(frozen=True)
class SetpointProblem:
    """Why a setpoint may not be played: sample ``sample`` (its index in the samples checked; ``len(samples)`` for
    the step to ``following``) breaks the check ``kind`` (``finite``, ``envelope``, ``stroke``, ``rate``);
    ``detail`` says where and by how much in ASCII, e.g. ``heave 0.3 m outside [-0.1800, 0.1800] m``."""

    sample: int
    kind: str
    detail: str

    def message(self) -> str:
        """One line, e.g. ``sample 3: heave 0.3 m outside [-0.1800, 0.1800] m``."""
        return f"sample {self.sample}: {self.detail}"


def check_setpoints(table: TableModel, samples: np.ndarray, spacing_s: float,
                    previous: tuple[np.ndarray, float] | None = None,
                    following: tuple[np.ndarray, float] | None = None) -> SetpointProblem | None:
    """The first problem of ``samples`` (n, 6), evenly spaced by ``spacing_s`` [s], on ``table``; None when every
    sample may be played (module docstring). ``previous`` is the pose (6,) played before the first sample and how
    long before it [s]; ``following`` the pose after the last one and how long after it [s] (a step over no time,
    ``≤ 0`` s, is not checked)."""
    samples = np.asarray(samples, dtype=np.float64).reshape(-1, 6)
    n = len(samples)
    if n == 0:
        return None
    finite = np.asarray(np.isfinite(samples).all(axis=1))
    lim, g = table.limits, table.geometry
    bounds = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                       lim.tilt.angle, lim.tilt.angle, np.inf])
    clean = np.where(finite[:, None], samples, 0.0)
    outside = np.abs(clean) > bounds + POSITION_ALLOWANCE
    inside = finite & ~outside.any(axis=1)
    before, after = _neighbour(previous), _neighbour(following)
    poses = np.vstack([*([before[0]] if before else []), np.where(inside[:, None], clean, 0.0),
                       *([after[0]] if after else [])])
    all_lengths = table.leg_lengths(poses)  # one pass: the neighbours' lengths for the rates too
    lengths = all_lengths[1:1 + n] if before else all_lengths[:n]
    over = (lengths > g.leg_max + POSITION_ALLOWANCE) | (lengths < g.leg_min - POSITION_ALLOWANCE)
    sound = inside & ~over.any(axis=1)
    problems = [_first_non_finite(samples, finite), _first_outside(clean, outside, bounds),
                _first_stroke(lengths, over, table)]
    if sound.all():
        times = spacing_s * np.arange(n, dtype=np.float64)
        times = np.concatenate([[-before[1]] if before else [], times, [times[-1] + after[1]] if after else []])
        problems.append(_first_rate(table, poses, all_lengths, times, 0 if before else 1))
    found = [p for p in problems if p is not None]
    return min(found, key=lambda p: p.sample) if found else None


def _neighbour(given: tuple[np.ndarray, float] | None) -> tuple[np.ndarray, float] | None:
    """A neighbouring pose and its distance in time [s], when it is one to check a step against (finite, over
    more than no time)."""
    if given is None or not given[1] > 0 or not np.isfinite(given[0]).all():
        return None
    return np.asarray(given[0], dtype=np.float64), float(given[1])


def _first_non_finite(samples: np.ndarray, finite: np.ndarray) -> SetpointProblem | None:
    if finite.all():
        return None
    row = int(np.argmin(finite))
    column = int(np.argmin(np.isfinite(samples[row])))
    return SetpointProblem(row, "finite", f"{_COLUMNS[column]} {float(samples[row, column])} is not a finite number")


def _first_outside(clean: np.ndarray, outside: np.ndarray, bounds: np.ndarray) -> SetpointProblem | None:
    rows = np.flatnonzero(outside.any(axis=1))
    if not len(rows):
        return None
    row = int(rows[0])
    column = int(np.argmax(outside[row]))
    unit = "m" if column < 3 else "rad"
    bound = bounds[column]
    return SetpointProblem(row, "envelope", f"{_COLUMNS[column]} {clean[row, column]:.4g} {unit} outside "
                                            f"[{-bound:.4f}, {bound:.4f}] {unit}")


def _first_stroke(lengths: np.ndarray, over: np.ndarray, table: TableModel) -> SetpointProblem | None:
    rows = np.flatnonzero(over.any(axis=1))
    if not len(rows):
        return None
    row = int(rows[0])
    leg = int(np.argmax(over[row]))
    g = table.geometry
    return SetpointProblem(row, "stroke", f"leg {leg + 1} length {lengths[row, leg]:.4f} m outside its stroke "
                                          f"[{g.leg_min:.4f}, {g.leg_max:.4f}] m")


def _first_rate(table: TableModel, poses: np.ndarray, all_lengths: np.ndarray, times: np.ndarray, first: int
                ) -> SetpointProblem | None:
    """The first step between consecutive ``poses`` (their leg lengths ``all_lengths``, at ``times`` [s]) whose leg
    speed or tilt rate is beyond its limit, numbered by the sample it ends at: step k ends at sample ``k + first``
    (``first`` 0 when the first pose is the one before the samples, else 1)."""
    if len(poses) < 2:
        return None
    dt = np.diff(times)[:, None]
    leg_speed = np.abs(np.diff(all_lengths, axis=0)) / dt
    tilt_rate = np.abs(np.diff(poses[:, 3:5], axis=0)) / dt
    g, lim = table.geometry, table.limits
    legs_over = leg_speed > g.leg_speed * (1 + RATE_ALLOWANCE)
    tilts_over = tilt_rate > lim.tilt.rate * (1 + RATE_ALLOWANCE)
    steps = np.flatnonzero(legs_over.any(axis=1) | tilts_over.any(axis=1))
    if not len(steps):
        return None
    step = int(steps[0])
    sample = step + first
    if legs_over[step].any():
        leg = int(np.argmax(legs_over[step]))
        detail = (f"leg {leg + 1} moves at {leg_speed[step, leg]:.4g} m/s from the sample before, beyond its "
                  f"speed {g.leg_speed:.4f} m/s")
    else:
        axis = int(np.argmax(tilts_over[step]))
        detail = (f"{TILTS[axis]} turns at {tilt_rate[step, axis]:.4g} rad/s from the sample before, beyond the tilt "
                  f"rate {lim.tilt.rate:.4f} rad/s")
    return SetpointProblem(sample, "rate", detail)
