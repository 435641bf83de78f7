"""Servo-hydraulic legs: the table's dynamics behind ``rig emulate --dynamics servo`` (``docs/table-dynamics.md``).

Each leg is a servo-valve feeding a double-acting cylinder whose oil column is a spring under the moving mass
(``analysis.table.dynamics.TableDynamics``: k_h = 4βA²/V_t, ω_h = sqrt(k_h/m)), closed by the controller's digital
displacement loop at the controller rate. Per leg, with the valve's flow written as a piston speed w [m/s]:

    valve        ẇ_a = ω_v (w − w_a)                   first-order, ω_v = 2π·valve_bandwidth
    oil column   ẏ   = w_a − v                         y: the column's compression [m], force k_h·y
    mass         v̇   = ω_h² y − 2 ζ ω_h v,   L̇ = v      L: leg length [m]

and, once per tick (sampled, the valve command w held over the tick), the controller's law

    w_k = K_v (r_k − L_k) + f (r_k − r_{k−1}) / dt,    |w_k| ≤ leg_speed  (the valve's flow saturates)

with r the leg's commanded length, K_v the loop gain and f the velocity feed-forward. The plant is discretised
exactly for the held command (``scipy.signal.cont2discrete``, zero-order hold), so the recursion is exact between
samples. From r to L the continuous closed loop is

    H(s) = G(s) (K_v + f s) / (s + K_v G(s)),   G(s) = ω_v/(s + ω_v) · ω_h²/(s² + 2ζω_h s + ω_h²)

(:meth:`ServoActuators.closed_loop`); :meth:`ServoActuators.discrete_closed_loop` is the sampled loop the emulator
runs (tests compare the simulated legs with both). The plate's achieved acceleration therefore shows the oil-column
resonance (amplified near ω_h, filtered above it) and the loop's phase lag.

Interface as :class:`sim_table.actuators.Actuators` (which stays the default, ``--dynamics lag``): the reference pose
is clipped to the per-axis envelope and the legs' commands to their stroke; braked drives (and a seized leg,
:attr:`ServoActuators.stalled`) close their valve command at ``brake_deceleration``; leg readings carry noise
(:meth:`ServoActuators.measure`). The batch runs in one numba loop over ticks and legs.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from analysis.table.dynamics import TableDynamics
from analysis.table.model import TableModel
from sim_table.actuators import Actuators, ActuatorSettings, ActuatorStep
from sim_table.options import DYNAMICS

if TYPE_CHECKING:  # scipy.signal takes 0.6 s to import: only the servo model needs it, when built
    from scipy.signal import TransferFunction, dlti


@njit(cache=True)
def _run(ad: np.ndarray, bd: np.ndarray, state: np.ndarray, last_ref: np.ndarray, last_w: np.ndarray,
         commanded: np.ndarray, braked: np.ndarray, stalled: np.ndarray, gain: float, feedforward: float, dt: float,
         w_max: float, brake: float, leg_min: float, leg_max: float, out: np.ndarray) -> bool:
    """Advance the legs' ``state`` (6, 4: w_a, y, L, v) over the ticks of ``commanded`` (k, 6) in place; the
    lengths at the ticks' ends into ``out`` (k, 6); whether a valve saturated."""
    saturated = False
    n = state.shape[1]
    nxt = np.empty(n)
    for i in range(commanded.shape[0]):
        for leg in range(6):
            s = state[leg]
            if braked[i] or stalled[leg]:
                held = last_w[leg]
                w = math.copysign(max(abs(held) - brake, 0.0), held)
            else:
                w = gain * (commanded[i, leg] - s[2]) + feedforward * (commanded[i, leg] - last_ref[leg]) / dt
                if abs(w) > w_max:
                    saturated = True
                    w = math.copysign(w_max, w)
            for a in range(n):
                acc = bd[a] * w
                for b in range(n):
                    acc += ad[a, b] * s[b]
                nxt[a] = acc
            if nxt[2] < leg_min or nxt[2] > leg_max:  # the cylinder's end stop
                nxt[2] = min(max(nxt[2], leg_min), leg_max)
                nxt[3] = 0.0
            for a in range(n):
                s[a] = nxt[a]
            last_w[leg] = w
            last_ref[leg] = s[2] if (braked[i] or stalled[leg]) else commanded[i, leg]
            out[i, leg] = s[2]
    return saturated


class ServoActuators:
    """Six servo-hydraulic legs on ``table`` (module docstring), ticking every ``dt`` s, at rest at ``pose``
    (default home); ``payload`` [kg] of specimens on the plate; the servo parameters are ``table.dynamics``
    unless ``dynamics`` is given; ``settings`` gives the measurement noise and brake deceleration."""

    def __init__(self, table: TableModel, dt: float, settings: ActuatorSettings | None = None, *,
                 dynamics: TableDynamics | None = None, payload: float = 0.0, pose: np.ndarray | None = None,
                 seed: int = 0) -> None:
        self.table = table
        self.dt = float(dt)
        self.settings = settings or ActuatorSettings()
        self.dynamics = dynamics or table.dynamics
        if not (math.isfinite(payload) and payload >= 0):
            raise ValueError(f"payload must be >= 0 kg, got {payload!r}")
        self.payload = float(payload)
        g, lim = table.geometry, table.limits
        self.omega_h = self.dynamics.oil_column_frequency(g.leg_max - g.leg_min, self.payload)
        """The oil-column frequency ω_h [rad/s] under the plate and payload."""
        self._ad, self._bd = self._plant()
        self._bound = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                                lim.tilt.angle, lim.tilt.angle, math.inf])
        self._rng = np.random.default_rng(seed)
        self.pose = np.zeros(6) if pose is None else np.array(pose, dtype=float)
        """The true achieved pose after the last tick."""
        self.lengths = table.leg_lengths(self.pose)
        """The true leg lengths after the last tick [m]."""
        self._state = np.zeros((6, 4))
        self._state[:, 2] = self.lengths
        self._last_ref = self.lengths.copy()
        self._last_w = np.zeros(6)
        self._offset: np.ndarray | float = 0.0  # achieved − reference pose at the last tick, and its change per
        self._drift: np.ndarray | float = 0.0   # tick: the kinematics' guess extrapolates them (one Newton step)
        self.stalled = np.zeros(6, dtype=bool)
        """Legs whose actuator seized (set by the owner): their valve command decays to zero at the brake rate."""
        self._advance(np.zeros((0, 6)), np.zeros(0, dtype=bool))  # compile (or load) the numba loop now, not mid-stream

    # ----- the model ----------------------------------------------------------------------------------

    def _continuous(self) -> tuple[np.ndarray, np.ndarray]:
        """The plant's continuous state-space (A, B), state (w_a, y, L, v), input the valve command w [m/s]."""
        wv = 2.0 * math.pi * self.dynamics.valve_bandwidth
        wh, zeta = self.omega_h, self.dynamics.damping_ratio
        a = np.array([[-wv, 0.0, 0.0, 0.0],                   # ẇ_a = ω_v (w − w_a)
                      [1.0, 0.0, 0.0, -1.0],                   # ẏ = w_a − v
                      [0.0, 0.0, 0.0, 1.0],                    # L̇ = v
                      [0.0, wh * wh, 0.0, -2.0 * zeta * wh]])  # v̇ = ω_h² y − 2ζω_h v
        b = np.array([wv, 0.0, 0.0, 0.0])
        return a, b

    def _plant(self) -> tuple[np.ndarray, np.ndarray]:
        from scipy.signal import cont2discrete

        a, b = self._continuous()
        ad, bd, *_ = cont2discrete((a, b[:, None], np.eye(4), np.zeros((4, 1))), self.dt, method="zoh")
        return np.ascontiguousarray(ad), np.ascontiguousarray(bd[:, 0])

    def closed_loop(self) -> TransferFunction:
        """The continuous closed loop H(s) = L/r (module docstring) as a ``scipy.signal.TransferFunction``."""
        from scipy.signal import TransferFunction

        d = self.dynamics
        wv, wh, zeta = 2.0 * math.pi * d.valve_bandwidth, self.omega_h, d.damping_ratio
        g_num = np.array([wv * wh * wh])
        g_den = np.polymul([1.0, wv], [1.0, 2.0 * zeta * wh, wh * wh])
        num = np.polymul(g_num, [d.velocity_feedforward, d.loop_gain])
        den = np.polyadd(np.polymul([1.0, 0.0], g_den), d.loop_gain * g_num)
        return TransferFunction(num, den)

    def discrete_closed_loop(self) -> dlti:
        """The sampled loop the legs run (no saturation), input r_k, output L at the tick's end, as a ``dlti``."""
        from scipy.signal import dlti

        d, ad, bd = self.dynamics, self._ad, self._bd
        c = np.array([0.0, 0.0, 1.0, 0.0])
        kv, f = d.loop_gain, d.velocity_feedforward / self.dt
        a = np.zeros((5, 5))
        a[:4, :4] = ad - kv * np.outer(bd, c)
        a[:4, 4] = -f * bd
        b = np.zeros((5, 1))
        b[:4, 0] = (kv + f) * bd
        b[4, 0] = 1.0
        cz = np.zeros((1, 5))
        cz[0, :4] = c @ a[:4, :4]
        cz[0, 4] = -f * (c @ bd)
        dz = np.array([[(kv + f) * (c @ bd)]])
        return dlti(a, b, cz, dz, dt=self.dt)

    # ----- the interface of sim_table.actuators.Actuators ---------------------------------------------

    def step(self, reference: np.ndarray, braked: np.ndarray) -> ActuatorStep:
        """Run k ticks: ``reference`` (k, 6) poses, ``braked`` (k,) whether the drives are braked at each."""
        reference = np.asarray(reference, dtype=float)
        braked = np.asarray(braked, dtype=bool)
        clipped = np.clip(reference, -self._bound, self._bound)
        setpoint_limited = not np.array_equal(clipped, reference)
        g = self.table.geometry
        wanted = self.table.leg_lengths(clipped)
        commanded = np.clip(wanted, g.leg_min, g.leg_max)
        stroke_limited = not np.array_equal(commanded, wanted)
        out, saturated = self._advance(commanded, braked)
        ahead = np.arange(1, len(clipped) + 1)[:, None]
        guess = np.where(braked[:, None], self.pose, clipped + self._offset + self._drift * ahead)
        poses = self.table.pose_from_leg_lengths(out, guess=guess)
        self.pose, self.lengths = poses[-1], out[-1].copy()
        offsets = poses - clipped
        if braked.any() or len(poses) < 2:
            self._offset, self._drift = (0.0, 0.0) if braked[-1] else (offsets[-1], 0.0)
        else:
            self._offset, self._drift = offsets[-1], offsets[-1] - offsets[-2]
        demand = np.where(braked[:, None], out, commanded)
        return ActuatorStep(poses, out, demand, setpoint_limited or saturated, stroke_limited)

    def _advance(self, commanded: np.ndarray, braked: np.ndarray) -> tuple[np.ndarray, bool]:
        """The legs over the ticks of ``commanded`` (k, 6) leg lengths: their lengths (k, 6), whether a valve
        saturated."""
        g = self.table.geometry
        out = np.empty_like(commanded)
        saturated = _run(self._ad, self._bd, self._state, self._last_ref, self._last_w, commanded, braked,
                         self.stalled, self.dynamics.loop_gain, self.dynamics.velocity_feedforward, self.dt,
                         g.leg_speed, self.settings.brake_deceleration * self.dt, g.leg_min, g.leg_max, out)
        return out, bool(saturated)

    def measure(self, lengths: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The measured pose (6,): forward kinematics of the leg ``lengths`` (6,) read with noise, from ``pose``."""
        readings = lengths + self._rng.normal(0.0, self.settings.noise, 6) if self.settings.noise else lengths
        return self.table.pose_from_leg_lengths(readings, guess=pose)


def make_actuators(kind: str, table: TableModel, dt: float, settings: ActuatorSettings, *, payload: float = 0.0,
                   pose: np.ndarray | None = None, seed: int = 0) -> Actuators | ServoActuators:
    """The emulator's legs of model ``kind`` (:data:`DYNAMICS`) at rest at ``pose`` (default home); ``payload``: the
    specimens' mass [kg]."""
    if kind == "lag":
        return Actuators(table, dt, settings, pose=pose, seed=seed)
    if kind == "servo":
        return ServoActuators(table, dt, settings, payload=payload, pose=pose, seed=seed)
    raise ValueError(f"unknown dynamics {kind!r}: expected one of {', '.join(DYNAMICS)}")
