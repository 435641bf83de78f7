"""Point-to-point moves of the table: the quintic profile every part of the rig uses (one copy).

A move from pose ``start`` to ``end`` over a duration T follows ``start + (end − start)·s(τ)``, τ = t / T,
``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵``: position, rate and acceleration are continuous (rate and acceleration zero at both
ends) and the jerk is bounded. For a change Δ of one axis the peaks are

* rate ``15/8 · Δ / T`` at τ = 1/2;
* acceleration ``10/√3 · Δ / T²`` at τ = 1/2 ∓ √3/6;
* jerk ``60 · Δ / T³`` at τ = 0 and 1;

so :func:`shortest_duration` is the shortest T that keeps all three inside an axis's limits. The tilt ramps of a
prepared drive (``rig.drive.tilt``), the emulator's HOME/SET_TILT/return home (``sim_table.controller``) and a
CANopen master's own moves (``drivers.canopen``) are all this profile. Poses as in ``analysis.table.model``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.table.model import TableModel

RATE_PEAK = 15.0 / 8.0
ACCELERATION_PEAK = 10.0 / math.sqrt(3.0)
JERK_PEAK = 60.0


def quintic(tau: np.ndarray | float) -> np.ndarray | float:
    """``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (τ in [0, 1])."""
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)


def shortest_duration(change: np.ndarray | float, velocity: np.ndarray | float, acceleration: np.ndarray | float,
                      jerk: np.ndarray | float) -> float:
    """Shortest quintic move [s] for changes ``change`` (per axis) within the axes' rate, acceleration and jerk
    limits (same units per axis; ``inf`` for a limit that does not apply)."""
    change = np.abs(np.asarray(change, dtype=np.float64))
    times = np.maximum.reduce([RATE_PEAK * change / velocity, np.sqrt(ACCELERATION_PEAK * change / acceleration),
                               np.cbrt(JERK_PEAK * change / jerk)])
    return float(np.max(times))


def axis_limits(table: TableModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pose column: velocity [m/s, rad/s], acceleration [m/s², rad/s²] and jerk (inf for translations)."""
    lim = table.limits
    axes, tilt = (lim.surge, lim.lateral, lim.heave), lim.tilt
    return (np.array([a.velocity for a in axes] + [tilt.rate] * 3),
            np.array([a.acceleration for a in axes] + [tilt.acceleration] * 3),
            np.array([math.inf] * 3 + [tilt.jerk] * 3))


IN_POSITION = 2e-5
"""The in-position window [m for translations, rad for rotations]: a move (home, tilt, the return home of a stop)
has ended when its reference has arrived *and* the achieved pose is within this of its end on every axis (a
drive's "target reached", CiA 402 statusword bit 10 with its window 0x6067), so that a table reported at rest
is at rest. 20 µm: the emulator's legs (5 ms lag) settle into it about 45 ms after a 0.1 m move; their 1 µm
reading noise is well inside."""

SETTLE_TIME_NS = 500_000_000
"""How long after its reference has arrived a move may take to come into position [ns] before the table faults
(a following error: a leg that does not reach its command)."""


@dataclass(frozen=True, eq=False)
class Move:
    """A quintic move from pose ``start`` to ``end`` (6,) over [t0_ns, t0_ns + duration_ns] (integer ns)."""

    t0_ns: int
    start: np.ndarray
    end: np.ndarray
    duration_ns: int

    @classmethod
    def shortest(cls, t0_ns: int, start: np.ndarray, end: np.ndarray, table: TableModel) -> Move:
        """The shortest move within the table's axis limits (:func:`axis_limits`)."""
        duration = shortest_duration(np.asarray(end) - np.asarray(start), *axis_limits(table))
        return cls(t0_ns, np.array(start, dtype=np.float64), np.array(end, dtype=np.float64),
                   math.ceil(duration * 1e9))

    @property
    def end_ns(self) -> int:
        """When the move arrives [ns]."""
        return self.t0_ns + self.duration_ns

    def at(self, t_ns: int) -> np.ndarray:
        """The pose at ``t_ns`` (``start`` before the move, ``end`` after it)."""
        tau = min(1.0, max(0.0, (t_ns - self.t0_ns) / self.duration_ns)) if self.duration_ns > 0 else 1.0
        return self.start + (self.end - self.start) * quintic(tau)

    def done(self, t_ns: int) -> bool:
        """Whether the move's reference has arrived at ``t_ns``."""
        return t_ns >= self.end_ns

    def in_position(self, achieved: np.ndarray) -> bool:
        """Whether the ``achieved`` pose (6,) is within :data:`IN_POSITION` of the move's end on every axis."""
        return bool(np.all(np.abs(np.asarray(achieved) - self.end) <= IN_POSITION))

    def settle_overdue(self, t_ns: int) -> bool:
        """Whether :data:`SETTLE_TIME_NS` has passed since the reference arrived."""
        return t_ns - self.end_ns > SETTLE_TIME_NS
