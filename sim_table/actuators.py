"""The hexapod's six actuators on the table model: reference poses → leg lengths → achieved poses.

Per tick of ``dt`` seconds (``docs/table-controller.md``, "The emulator's physics"):

1. The reference pose is clipped to the per-axis envelope (|surge|, |sway| ≤ their displacement limits, |heave|
   likewise, |roll|, |pitch| ≤ the tilt angle; yaw is not limited): ``setpoint_limited``.
2. Inverse kinematics (``TableModel.leg_lengths``) gives each leg's commanded length, clipped to
   [leg_min, leg_max]: ``stroke_limited``.
3. Each leg follows its command as a first-order lag of time constant τ, exact for a command held over the
   tick: ``L ← c + (L − c)·e^(−dt/τ)``; its change per tick is limited to ``leg_speed·dt`` (``setpoint_limited``
   when that bites). With the drives braked (idle, faulted, emergency stop) the legs ignore the command and
   their speed decays at ``brake_deceleration`` to rest; so does, for good, a leg whose actuator seized
   (:attr:`Actuators.stalled`, an injected fault).
4. Forward kinematics (``TableModel.pose_from_leg_lengths``'s Newton, compiled: ``sim_table.forward_kinematics``)
   gives the achieved pose: Newton from the previous
   achieved pose advanced by the same lag applied to the poses (within ~1e-8 m of the answer, so one Newton step
   reaches the 1e-12 m tolerance; from the previous pose itself it takes two).

The legs' true motion is smooth; **noise** belongs to their measurement (``noise`` [m], σ of each leg-length
reading, seeded): :meth:`Actuators.measure` turns noisy leg readings into the measured pose the controller
reports. The plate's physics (accelerometers, specimens) sees the true motion: a position noise of σ would add
σ/dt² to any acceleration taken from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.compiled_index import njit
from analysis.table.model import TableModel
from sim_table.forward_kinematics import ForwardKinematics


@njit(cache=True)
def _first_order_lag(commanded: np.ndarray, start: np.ndarray, decay: float) -> np.ndarray:
    """``y[i] = c[i] + (y[i−1] − c[i])·decay`` over the rows of ``commanded`` (k, m), from ``y[−1] = start`` (m,)."""
    out = np.empty_like(commanded)
    y = start.copy()
    for i in range(commanded.shape[0]):
        for j in range(commanded.shape[1]):
            y[j] = commanded[i, j] + (y[j] - commanded[i, j]) * decay
            out[i, j] = y[j]
    return out


@dataclass(frozen=True)
class ActuatorSettings:
    """``time_constant`` τ [s] of each leg's lag, ``noise`` σ [m] of a leg-length reading,
    ``brake_deceleration`` [m/s²] of a leg when the drives are braked."""

    time_constant: float = 0.005
    noise: float = 1e-6
    brake_deceleration: float = 20.0

    def __post_init__(self) -> None:
        if not (self.time_constant > 0 and self.noise >= 0 and self.brake_deceleration > 0):
            raise ValueError(f"actuator settings need τ > 0, noise ≥ 0, brake deceleration > 0: {self}")


@dataclass(frozen=True, eq=False)
class ActuatorStep:
    """Ticks of the actuators: true achieved ``poses`` (k, 6) and leg ``lengths`` (k, 6) [m] at the ticks' ends,
    each leg's ``commanded`` length (k, 6) [m] in the ticks (its drive's position demand: the command it follows,
    its own length while the drives are braked); whether a reference left the per-axis envelope or met a leg's
    speed limit (``setpoint_limited``) or a leg's command left its stroke (``stroke_limited``)."""

    poses: np.ndarray
    lengths: np.ndarray
    commanded: np.ndarray
    setpoint_limited: bool
    stroke_limited: bool


class Actuators:
    """Six lagged, rate- and stroke-limited legs on ``table``, ticking every ``dt`` s, starting at rest at
    ``pose`` (6,) (default home); measurement noise drawn from ``seed``."""

    def __init__(self, table: TableModel, dt: float, settings: ActuatorSettings | None = None, *,
                 pose: np.ndarray | None = None, seed: int = 0) -> None:
        self.table = table
        self.dt = float(dt)
        self.settings = settings or ActuatorSettings()
        g, lim = table.geometry, table.limits
        self._decay = math.exp(-self.dt / self.settings.time_constant)
        self._max_step = g.leg_speed * self.dt
        self._bound = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                                lim.tilt.angle, lim.tilt.angle, math.inf])
        self._rng = np.random.default_rng(seed)
        self.pose = np.zeros(6) if pose is None else np.array(pose, dtype=float)
        """The true achieved pose after the last tick."""
        self.lengths = table.leg_lengths(self.pose)
        """The true leg lengths after the last tick [m]."""
        self._rate = np.zeros(6)
        self.stalled = np.zeros(6, dtype=bool)
        """Legs whose actuator seized (set by the owner: injected fault): they brake to rest and stop following
        their command."""
        self._filter(np.zeros((0, 6)), self.lengths)  # compile (or load) the numba loop now, not mid-stream
        self._kinematics = ForwardKinematics(table)

    def step(self, reference: np.ndarray, braked: np.ndarray) -> ActuatorStep:
        """Run k ticks: ``reference`` (k, 6) poses, ``braked`` (k,) whether the drives are braked at each."""
        reference = np.asarray(reference, dtype=float)
        clipped = np.clip(reference, -self._bound, self._bound)
        setpoint_limited = not np.array_equal(clipped, reference)
        g = self.table.geometry
        wanted = self.table.leg_lengths(clipped)
        commanded = np.clip(wanted, g.leg_min, g.leg_max)
        stroke_limited = not np.array_equal(commanded, wanted)
        out = self._lag(commanded) if not (braked.any() or self.stalled.any()) else None
        if out is None:
            out, rate_limited = self._lag_tick_by_tick(commanded, braked)
            setpoint_limited = setpoint_limited or rate_limited
            guess = np.broadcast_to(self.pose, clipped.shape)
        else:
            guess = self._filter(clipped, self.pose)
        poses = self._kinematics.poses(out, guess)
        self.pose = poses[-1]
        demand = np.where(braked[:, None], out, commanded)
        return ActuatorStep(poses, out, demand, setpoint_limited, stroke_limited)

    def _filter(self, commanded: np.ndarray, start: np.ndarray) -> np.ndarray:
        """The lag ``y ← c + (y − c)·e^(−dt/τ)`` run over k commands (k, 6) from ``start`` (6,), as one filter."""
        return _first_order_lag(np.require(commanded, np.float64, ("C", "W")), np.array(start, dtype=np.float64),
                                self._decay)

    def _lag(self, commanded: np.ndarray) -> np.ndarray | None:
        """The legs over k driven ticks; None if a leg would pass its speed limit."""
        out = self._filter(commanded, self.lengths)
        changes = np.diff(out, axis=0, prepend=self.lengths[None, :])
        if np.abs(changes).max() > self._max_step:
            return None
        self.lengths, self._rate = out[-1], changes[-1] / self.dt
        return out

    def _lag_tick_by_tick(self, commanded: np.ndarray, braked: np.ndarray) -> tuple[np.ndarray, bool]:
        """The legs tick by tick with speed limits and brakes (a stalled leg brakes while the others follow);
        whether a speed limit bit."""
        g = self.table.geometry
        out = np.empty_like(commanded)
        length, rate = self.lengths, self._rate
        brake = self.settings.brake_deceleration * self.dt
        stalled = self.stalled.copy() if self.stalled.any() else None
        limited = False
        for i in range(len(commanded)):
            if braked[i]:
                rate = np.sign(rate) * np.maximum(np.abs(rate) - brake, 0.0)
                change = rate * self.dt
            else:
                change = (commanded[i] - length) * (1.0 - self._decay)
                if stalled is not None:
                    held = rate[stalled]
                    change[stalled] = np.sign(held) * np.maximum(np.abs(held) - brake, 0.0) * self.dt
                if np.abs(change).max() > self._max_step:
                    limited = True
                    change = np.clip(change, -self._max_step, self._max_step)
                rate = change / self.dt
            length = np.clip(length + change, g.leg_min, g.leg_max)
            out[i] = length
        self.lengths, self._rate = length, rate
        return out, limited

    def measure(self, lengths: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The measured poses (..., 6): forward kinematics of the leg ``lengths`` (..., 6) read with noise, from
        ``pose`` (..., 6); several at once read the noise as one after the other would."""
        lengths = np.asarray(lengths, dtype=float)
        readings = (lengths + self._rng.normal(0.0, self.settings.noise, lengths.shape) if self.settings.noise
                    else lengths)
        return self._kinematics.poses(readings, pose)
