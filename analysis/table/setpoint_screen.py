"""The setpoint check's compiled screen: whether a chunk of setpoints clearly passes every check of
:mod:`analysis.table.setpoints`, in one numba pass over its samples (a few µs for a chunk, where the numpy check
takes tens of µs: the controller checks every chunk it receives).

:meth:`SetpointScreen.clears` answers True only when every quantity the check bounds — each coordinate's finiteness, the
envelope, each leg's length against its stroke, each leg's speed and the roll and pitch rates over each step,
the steps from ``previous`` and to ``following`` included — is inside its limit (allowances included) by more than
:data:`SCREEN_MARGIN` of that limit. Its arithmetic is the check's (the same rotation, leg vectors and lengths),
so it can differ from the check's only by rounding, ~1e-16 relative, far inside the margin: a chunk it clears is
one :func:`~analysis.table.setpoints.check_setpoints` passes. Any other chunk — one with a problem, or one within
the margin of a limit — goes to :func:`~analysis.table.setpoints.check_setpoints`, which decides and says why: the
decisions and the reasons are the check's alone.

Units as in :mod:`analysis.table.setpoints`: poses ``(surge, sway, heave [m], roll, pitch, yaw [rad])``, times [s].
"""

from __future__ import annotations

import math

import numpy as np

from analysis.compiled_index import njit
from analysis.table.model import TableModel
from analysis.table.setpoints import POSITION_ALLOWANCE, RATE_ALLOWANCE

SCREEN_MARGIN = 1e-9
"""Share of each limit by which the screen wants a quantity inside it to clear the chunk: far above the rounding by
which its arithmetic can differ from the check's (~1e-16), far below anything a drive comes that close to."""


class SetpointScreen:
    """The screen of one table's setpoints (module docstring): its limits and joints held as the compiled pass
    takes them."""

    def __init__(self, table: TableModel) -> None:
        g, lim = table.geometry, table.limits
        self._joints = np.ascontiguousarray(np.stack([g.base_joints, g.platform_joints]), dtype=np.float64)
        a = POSITION_ALLOWANCE
        self._limits = np.array([lim.surge.displacement + a, lim.lateral.displacement + a, lim.heave.displacement + a,
                                 lim.tilt.angle + a, lim.tilt.angle + a, math.inf, g.leg_min - a, g.leg_max + a,
                                 g.leg_speed * (1 + RATE_ALLOWANCE), lim.tilt.rate * (1 + RATE_ALLOWANCE),
                                 g.home_height, SCREEN_MARGIN], dtype=np.float64)
        """Envelope (6) [m, rad], stroke (min, max) [m], leg speed [m/s], tilt rate [rad/s], each with its
        allowance; the home height [m]; :data:`SCREEN_MARGIN`."""
        self.clears(np.zeros((1, 6)), 1e-3)  # compile (or load) now, not at a stream's first chunk

    def clears(self, samples: np.ndarray, spacing_s: float, previous: tuple[np.ndarray, float] | None = None,
               following: tuple[np.ndarray, float] | None = None) -> bool:
        """Whether ``samples`` (n, 6), spaced by ``spacing_s`` [s], with the pose ``previous`` played that long [s]
        before the first and ``following`` that long after the last (as for
        :func:`~analysis.table.setpoints.check_setpoints`), clearly pass every check (module docstring); False
        when in any doubt."""
        samples = np.ascontiguousarray(samples, dtype=np.float64)
        if samples.ndim != 2 or samples.shape[1] != 6 or len(samples) == 0:
            return False
        neighbours = np.zeros((2, 6))
        seconds = np.array([spacing_s, _neighbour(previous, neighbours[0]), _neighbour(following, neighbours[1])])
        return bool(_clears(samples, neighbours, seconds, self._joints, self._limits))


def _neighbour(given: tuple[np.ndarray, float] | None, pose: np.ndarray) -> float:
    """A neighbouring pose put into ``pose`` (6,), and its distance in time [s]; 0 s when there is none to check a
    step against (as the check's: none given, over no time, or not finite)."""
    if given is None or not given[1] > 0:
        return 0.0
    pose[:] = given[0]
    return float(given[1]) if np.isfinite(pose).all() else 0.0


@njit(cache=True)
def _leg_lengths(pose: np.ndarray, base: np.ndarray, platform: np.ndarray, home_height: float,
                 out: np.ndarray) -> None:
    """The six leg lengths [m] at ``pose`` into ``out`` (6,), by ``analysis.table.kinematics.legs_at``'s
    arithmetic."""
    cr, cp, cy = math.cos(pose[3]), math.cos(pose[4]), math.cos(pose[5])
    sr, sp, sy = math.sin(pose[3]), math.sin(pose[4]), math.sin(pose[5])
    r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    r20, r21, r22 = -sp, cp * sr, cp * cr
    ox, oy, oz = pose[0], pose[1], pose[2] + home_height
    for k in range(6):
        qx, qy, qz = platform[k, 0], platform[k, 1], platform[k, 2]
        dx = (r00 * qx + r01 * qy + r02 * qz) + (ox - base[k, 0])
        dy = (r10 * qx + r11 * qy + r12 * qz) + (oy - base[k, 1])
        dz = (r20 * qx + r21 * qy + r22 * qz) + (oz - base[k, 2])
        out[k] = math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _step_clears(pose_a: np.ndarray, lengths_a: np.ndarray, pose_b: np.ndarray, lengths_b: np.ndarray,
                 seconds: float, leg_speed: float, tilt_rate: float, margin: float) -> bool:
    """Whether the step from pose a to pose b over ``seconds`` [s] clearly keeps every leg's speed and the roll
    and pitch rates inside their limits (allowances included)."""
    for k in range(6):
        if not abs(lengths_b[k] - lengths_a[k]) / seconds <= leg_speed * (1.0 - margin):
            return False
    roll_rate = abs(pose_b[3] - pose_a[3]) / seconds
    pitch_rate = abs(pose_b[4] - pose_a[4]) / seconds
    return roll_rate <= tilt_rate * (1.0 - margin) and pitch_rate <= tilt_rate * (1.0 - margin)


@njit(cache=True)
def _clears(samples: np.ndarray, neighbours: np.ndarray, seconds: np.ndarray, joints: np.ndarray,
            limits: np.ndarray) -> bool:
    """:meth:`SetpointScreen.clears` on plain arrays: ``neighbours`` (2, 6) the poses before and after, ``seconds``
    (3,) the spacing and their distances [s] (0: not checked), ``joints`` (2, 6, 3) the base and platform joints,
    ``limits`` as :class:`SetpointScreen` holds them."""
    base, platform = joints[0], joints[1]
    leg_min, leg_max, leg_speed, tilt_rate, home_height, margin = limits[6:12]
    n = samples.shape[0]
    lengths = np.empty((n, 6))
    for i in range(n):
        for column in range(6):
            value = samples[i, column]
            if not abs(value) <= limits[column] * (1.0 - margin):  # NaN and ±inf fail here too
                return False
        _leg_lengths(samples[i], base, platform, home_height, lengths[i])
        for k in range(6):
            if not (leg_min * (1.0 + margin) <= lengths[i, k] <= leg_max * (1.0 - margin)):
                return False
        if i > 0 and not _step_clears(samples[i - 1], lengths[i - 1], samples[i], lengths[i], seconds[0],
                                      leg_speed, tilt_rate, margin):
            return False
    neighbour = np.empty(6)
    if seconds[1] > 0.0:
        _leg_lengths(neighbours[0], base, platform, home_height, neighbour)
        if not _step_clears(neighbours[0], neighbour, samples[0], lengths[0], seconds[1], leg_speed, tilt_rate,
                            margin):
            return False
    if seconds[2] > 0.0:
        _leg_lengths(neighbours[1], base, platform, home_height, neighbour)
        if not _step_clears(samples[n - 1], lengths[n - 1], neighbours[1], neighbour, seconds[2], leg_speed,
                            tilt_rate, margin):
            return False
    return True
