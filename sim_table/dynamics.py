"""Servo-hydraulic legs under a rigid plate: the table's dynamics behind ``rig emulate --dynamics servo``
(``docs/table-dynamics.md``).

The plate is a rigid body (``analysis.table.dynamics``) on six oil columns along the legs' axes, each leg a
servo-valve feeding a double-acting cylinder, closed by the controller's digital displacement loop at the
controller rate. State in the legs' lengths L (6,) [m], the valves' flows as piston speeds w [m/s], the columns'
compressions y [m] (deviations from the static load) and the legs' rates v [m/s]. The eigenvectors of the legs'
mass matrix decouple six **modes**; each is discretised exactly for the valve command held over a tick
(:func:`_zoh`), the state turned into the modes' for each step so that saturation, brakes, a seized leg and the end
stops act on each leg. :meth:`ServoActuators.closed_loops`, :meth:`~ServoActuators.frequency_response`,
:meth:`~ServoActuators.discrete_closed_loops` and :meth:`~ServoActuators.loop_margins` give the loops the emulator
runs; the model is re-evaluated when the pose has moved more than :data:`RELINEARISE_M` [m] or
:data:`RELINEARISE_RAD` [rad].

Interface as :class:`sim_table.actuators.Actuators` (which stays the default, ``--dynamics lag``): the reference pose
is clipped to the per-axis envelope and the legs' commands to their stroke; braked drives (and a seized leg,
:attr:`ServoActuators.stalled`) close their valve command at ``brake_deceleration``; leg readings carry noise
(:meth:`ServoActuators.measure`). The batch runs in one numba loop over ticks, legs and modes.

The equations, the controller's law, the closed loops and what is left out: docs/table-dynamics.md §The plate on its
six legs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from analysis.compiled_index import njit
from analysis.table.dynamics import PlateLoad, TableDynamics
from analysis.table.model import TableModel
from sim_table.actuators import Actuators, ActuatorSettings, ActuatorStep
from sim_table.forward_kinematics import ForwardKinematics
from sim_table.options import DYNAMICS

if TYPE_CHECKING:  # scipy.signal takes 0.6 s to import: only the servo model's analysis needs it
    from scipy.signal import TransferFunction, dlti

    from sim_table.scene import Specimen

RELINEARISE_M = 0.01
"""Translation of the plate [m] after which its mass matrix and Jacobian are evaluated afresh."""

RELINEARISE_RAD = math.radians(0.5)
"""Rotation of the plate [rad] after which its mass matrix and Jacobian are evaluated afresh."""


@njit(cache=True)
def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b of two small square matrices, in plain loops (numba's ``@`` calls BLAS, slow for a 5 × 5)."""
    n = a.shape[0]
    out = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(n):
                    out[i, j] += aik * b[k, j]
    return out


@njit(cache=True)
def _zoh(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of ẋ = a x + b u over ``dt``: (e^{a dt}, ∫₀^dt e^{a t} dt b), from the
    exponential of the augmented matrix [[a, b], [0, 0]]·dt by scaling and squaring of its Taylor series (to
    machine precision: the scaled matrix has norm ≤ 1/2 and 20 terms)."""
    n = a.shape[0]
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a * dt
    m[:n, n] = b * dt
    norm = np.abs(m).sum(axis=1).max()
    squarings = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    m /= 2.0**squarings
    out = np.eye(n + 1)
    term = np.eye(n + 1)
    for k in range(1, 21):
        term = _product(term, m) / k
        out += term
    for _ in range(squarings):
        out = _product(out, out)
    return out[:n, :n].copy(), out[:n, n].copy()


@njit(cache=True)
def _modes(ad: np.ndarray, bd: np.ndarray, omega: np.ndarray, zeta: float, wv: float, dt: float) -> None:
    """Each mode's sampled plant into ``ad`` (6, 4, 4) and ``bd`` (6, 4): state (w_a, y, L, v), input w [m/s]."""
    for j in range(omega.shape[0]):
        wh = omega[j]
        a = np.array([[-wv, 0.0, 0.0, 0.0],                   # ẇ_a = ω_v (w − w_a)
                      [1.0, 0.0, 0.0, -1.0],                   # ẏ = w_a − v
                      [0.0, 0.0, 0.0, 1.0],                    # L̇ = v
                      [0.0, wh * wh, 0.0, -2.0 * zeta * wh]])  # v̇ = ω_j² y − 2ζω_j v
        b = np.array([wv, 0.0, 0.0, 0.0])
        ad[j], bd[j] = _zoh(a, b, dt)


@njit(cache=True)
def _leg_modes(pose: np.ndarray, base: np.ndarray, platform: np.ndarray, home_height: float, mass: float,
               first_moment: np.ndarray, inertia: np.ndarray, piston_mass: float) -> tuple[np.ndarray, np.ndarray]:
    """The legs' mass matrix M_L at ``pose`` (6,) split into its modes: (U (6, 6), μ (6,)), heaviest first.

    In twist coordinates (the platform origin's velocity, the angular velocity) the plate with its loads has the
    mass matrix [[m I, −[R h]ₓ], [[R h]ₓ, R I_o Rᵀ]] (``mass`` m [kg], ``first_moment`` h = Σ m c [kg·m] and
    ``inertia`` I_o about the platform origin [kg·m²], both in the platform frame), and the legs' rates are J_t times
    the twist, row i (u_i, R q_i × u_i) (u_i the unit leg vector, q_i the platform joint); M_L = J_t⁻ᵀ M J_t⁻¹ + m_p I.
    The Euler-rate map of the pose coordinates cancels out of M_L."""
    cr, sr = math.cos(pose[3]), math.sin(pose[3])
    cp, sp = math.cos(pose[4]), math.sin(pose[4])
    cy, sy = math.cos(pose[5]), math.sin(pose[5])
    rot = np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                    [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                    [-sp, cp * sr, cp * cr]])
    jacobian = np.empty((6, 6))
    for i in range(6):
        rq = rot @ platform[i]
        d = rq + pose[:3] - base[i]
        d[2] += home_height
        u = d / math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        jacobian[i, :3] = u
        jacobian[i, 3:] = np.cross(rq, u)
    r = rot @ first_moment
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    twist = np.zeros((6, 6))
    for a in range(3):
        twist[a, a] = mass
    twist[:3, 3:] = -skew
    twist[3:, :3] = skew
    twist[3:, 3:] = rot @ inertia @ rot.T
    inverse = np.linalg.inv(jacobian)
    legs = inverse.T @ twist @ inverse
    legs = 0.5 * (legs + legs.T)
    for a in range(6):
        legs[a, a] += piston_mass
    mu, modes = np.linalg.eigh(legs)
    return np.ascontiguousarray(modes[:, ::-1]), mu[::-1].copy()


@njit(cache=True)
def _run(u: np.ndarray, ad: np.ndarray, bd: np.ndarray, state: np.ndarray, last_ref: np.ndarray,
         last_w: np.ndarray, commanded: np.ndarray, braked: np.ndarray, stalled: np.ndarray, gain: float,
         feedforward: float, dt: float, w_max: float, brake: float, leg_min: float, leg_max: float,
         out: np.ndarray) -> bool:
    """Advance the legs' ``state`` (6, 4: w_a, y, L, v per leg) over the ticks of ``commanded`` (k, 6) in place, the
    modes U (``u``, 6 × 6, columns) stepping with ``ad`` (6, 4, 4), ``bd`` (6, 4); the lengths at the ticks' ends
    into ``out`` (k, 6); whether a valve saturated."""
    saturated = False
    w = np.empty(6)
    modal = np.empty((6, 4))
    stepped = np.empty((6, 4))
    for i in range(commanded.shape[0]):
        for leg in range(6):
            s = state[leg]
            if braked[i] or stalled[leg]:
                held = last_w[leg]
                w[leg] = math.copysign(max(abs(held) - brake, 0.0), held)
            else:
                w[leg] = gain * (commanded[i, leg] - s[2]) + feedforward * (commanded[i, leg] - last_ref[leg]) / dt
                if abs(w[leg]) > w_max:
                    saturated = True
                    w[leg] = math.copysign(w_max, w[leg])
        for j in range(6):  # into the modes: z = Uᵀ x
            wj = 0.0
            for leg in range(6):
                wj += u[leg, j] * w[leg]
            for a in range(4):
                acc = 0.0
                for leg in range(6):
                    acc += u[leg, j] * state[leg, a]
                modal[j, a] = acc
            for a in range(4):
                acc = bd[j, a] * wj
                for b in range(4):
                    acc += ad[j, a, b] * modal[j, b]
                stepped[j, a] = acc
        for leg in range(6):  # back to the legs: x = U z
            for a in range(4):
                acc = 0.0
                for j in range(6):
                    acc += u[leg, j] * stepped[j, a]
                state[leg, a] = acc
            if state[leg, 2] < leg_min or state[leg, 2] > leg_max:  # the cylinder's end stop
                state[leg, 2] = min(max(state[leg, 2], leg_min), leg_max)
                state[leg, 3] = 0.0
            last_w[leg] = w[leg]
            last_ref[leg] = state[leg, 2] if (braked[i] or stalled[leg]) else commanded[i, leg]
            out[i, leg] = state[leg, 2]
    return saturated


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of one mode's sampled displacement loop (its open loop K_v·P_j(z), P_j the mode's sampled
    plant from valve command to length): ``gain_margin`` [-] (the factor on K_v that makes the loop marginally
    stable) at ``phase_crossover_hz``, ``phase_margin_deg`` at ``gain_crossover_hz``."""

    gain_margin: float
    phase_crossover_hz: float
    phase_margin_deg: float
    gain_crossover_hz: float


def _rigid_sum(loads: Sequence[PlateLoad]) -> tuple[float, np.ndarray, np.ndarray]:
    """Rigid masses fixed to the plate as one: total mass [kg], first moment Σ m c [kg·m] and inertia tensor about
    the platform frame's origin Σ (I_c + m (|c|² I − c cᵀ)) [kg·m²], in the platform frame."""
    mass, first, inertia = 0.0, np.zeros(3), np.zeros((3, 3))
    for load in loads:
        c = np.asarray(load.centre, dtype=float)
        mass += load.mass
        first += load.mass * c
        inertia += np.diag(load.inertia) + load.mass * (c @ c * np.eye(3) - np.outer(c, c))
    return mass, first, inertia


def specimen_loads(specimens: Sequence[Specimen]) -> tuple[PlateLoad, ...]:
    """The specimens as rigid masses on the plate: each a homogeneous block b × depth × h standing upright at its
    place, its centre of gravity h/2 above the top surface (the analysis adds them to the plate's mass matrix)."""
    loads = []
    for s in specimens:
        b, d, h, m = s.body.b, s.depth, s.body.h, s.mass
        loads.append(PlateLoad(m, (s.x, s.y, 0.5 * h), (m * (d * d + h * h) / 12.0, m * (b * b + h * h) / 12.0,
                                                        m * (b * b + d * d) / 12.0)))
    return tuple(loads)


class ServoActuators:
    """Six servo-hydraulic legs under the rigid plate of ``table`` (module docstring), ticking every ``dt`` s, at
    rest at ``pose`` (default home); ``loads`` (specimens as :class:`~analysis.table.dynamics.PlateLoad`) and
    ``payload`` [kg] (a mass at the centre of the plate's top surface) ride on the plate; the servo parameters and
    the plate are ``table.dynamics`` unless ``dynamics`` is given; ``settings`` gives the measurement noise and
    brake deceleration."""

    def __init__(self, table: TableModel, dt: float, settings: ActuatorSettings | None = None, *,
                 dynamics: TableDynamics | None = None, payload: float = 0.0, loads: Sequence[PlateLoad] = (),
                 pose: np.ndarray | None = None, seed: int = 0) -> None:
        self.table = table
        self.dt = float(dt)
        self.settings = settings or ActuatorSettings()
        self.dynamics = dynamics or table.dynamics
        if not (math.isfinite(payload) and payload >= 0):
            raise ValueError(f"payload must be >= 0 kg, got {payload!r}")
        self.loads = (*loads, *((PlateLoad(float(payload), (0.0, 0.0, 0.0)),) if payload else ()))
        """What rides on the plate besides itself."""
        g, lim = table.geometry, table.limits
        self._k = self.dynamics.stiffness(g.leg_max - g.leg_min)
        self._bound = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                                lim.tilt.angle, lim.tilt.angle, math.inf])
        self._rng = np.random.default_rng(seed)
        self._kinematics = ForwardKinematics(table)
        self.pose = np.zeros(6) if pose is None else np.array(pose, dtype=float)
        """The true achieved pose after the last tick."""
        self.lengths = table.leg_lengths(self.pose)
        """The true leg lengths after the last tick [m]."""
        self._rigid = _rigid_sum((self.dynamics.plate(), *self.loads))
        self._ad, self._bd = np.zeros((6, 4, 4)), np.zeros((6, 4))
        self.linearise(self.pose)
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

    def linearise(self, pose: np.ndarray) -> None:
        """Evaluate the plate's mass matrix and the legs' Jacobian at ``pose`` (6,): the modes (:attr:`omega`,
        :attr:`modes`) and their sampled plants."""
        pose = np.array(pose, dtype=float)
        g, d = self.table.geometry, self.dynamics
        modes, mu = _leg_modes(pose, g.base_joints, g.platform_joints, g.home_height, *self._rigid, d.piston_mass)
        self.modes = modes
        """U (6, 6): column j the legs' motion in mode j (orthonormal: the eigenvectors of M_L)."""
        self.omega = np.sqrt(self._k / mu)
        """The modes' oil-column frequencies ω_j [rad/s], ascending."""
        self._lin_pose = pose
        _modes(self._ad, self._bd, self.omega, d.damping_ratio, 2.0 * math.pi * d.valve_bandwidth, self.dt)

    def closed_loops(self) -> list[TransferFunction]:
        """Each mode's continuous closed loop H_j(s) (module docstring) as a ``scipy.signal.TransferFunction``."""
        from scipy.signal import TransferFunction

        d = self.dynamics
        wv, zeta = 2.0 * math.pi * d.valve_bandwidth, d.damping_ratio
        loops = []
        for wh in self.omega:
            g_num = np.array([wv * wh * wh])
            g_den = np.polymul([1.0, wv], [1.0, 2.0 * zeta * wh, wh * wh])
            num = np.polymul(g_num, [d.velocity_feedforward, d.loop_gain])
            den = np.polyadd(np.polymul([1.0, 0.0], g_den), d.loop_gain * g_num)
            loops.append(TransferFunction(num, den))
        return loops

    def discrete_closed_loops(self) -> list[dlti]:
        """Each mode's sampled loop as the legs run it (no saturation), input r_k, output L at the tick's end, as a
        ``scipy.signal.dlti``."""
        from scipy.signal import dlti

        d = self.dynamics
        c = np.array([0.0, 0.0, 1.0, 0.0])
        kv, f = d.loop_gain, d.velocity_feedforward / self.dt
        loops = []
        for ad, bd in zip(self._ad, self._bd, strict=True):
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
            loops.append(dlti(a, b, cz, dz, dt=self.dt))
        return loops

    def open_loops(self) -> list[dlti]:
        """Each mode's sampled open loop K_v·P_j(z) from the position error to the length the controller reads at the
        next tick (the feed-forward is outside the loop), as a ``scipy.signal.dlti``."""
        from scipy.signal import dlti

        c = np.array([[0.0, 0.0, 1.0, 0.0]])
        kv = self.dynamics.loop_gain
        return [dlti(ad, kv * bd[:, None], c, np.zeros((1, 1)), dt=self.dt) for ad, bd in zip(self._ad, self._bd,
                                                                                           strict=True)]

    def loop_margins(self) -> list[LoopMargins]:
        """The stability margins of each mode's sampled loop (:meth:`open_loops`): the phase and gain crossovers on
        a 0.05 Hz … Nyquist grid of the open loop's frequency response, refined by root finding."""
        from scipy.optimize import brentq

        grid = np.geomspace(0.05, 0.499 / self.dt, 4000)
        margins = []
        for ad, bd in zip(self._ad, self._bd, strict=True):
            def response(hz: np.ndarray | float, ad: np.ndarray = ad, bd: np.ndarray = bd) -> np.ndarray:
                """K_v c (zI − A_d)⁻¹ b_d on the unit circle at ``hz``."""
                z = np.exp(2j * math.pi * np.atleast_1d(hz) * self.dt)
                solved = np.linalg.solve(z[:, None, None] * np.eye(4) - ad, np.broadcast_to(bd, (len(z), 4))[..., None])
                return self.dynamics.loop_gain * solved[:, 2, 0]

            values = response(grid)
            phase = np.unwrap(np.angle(values))
            below = np.flatnonzero((phase[:-1] > -math.pi) & (phase[1:] <= -math.pi))
            pc = (brentq(lambda hz: np.angle(-response(hz)[0]), grid[below[0]], grid[below[0] + 1])
                  if below.size else None)
            gain = np.abs(values)
            cross = np.flatnonzero((gain[:-1] >= 1.0) & (gain[1:] < 1.0))
            gc = (brentq(lambda hz: abs(response(hz)[0]) - 1.0, grid[cross[0]], grid[cross[0] + 1])
                  if cross.size else None)
            margins.append(LoopMargins(
                gain_margin=1.0 / abs(response(pc)[0]) if pc is not None else math.inf,
                phase_crossover_hz=pc if pc is not None else math.nan,
                phase_margin_deg=math.degrees(np.angle(response(gc)[0]) + math.pi) if gc is not None else math.inf,
                gain_crossover_hz=gc if gc is not None else math.nan))
        return margins

    def frequency_response(self, hz: np.ndarray, *, sampled: bool = True) -> np.ndarray:
        """The plate's response matrix (n, 6, 6), pose reference → achieved pose, at ``hz`` (n,) [Hz]:
        J⁻¹ U diag(H_j) Uᵀ J at the pose the modes were evaluated at, H_j the sampled loops (or, ``sampled=False``,
        the continuous ones)."""
        from scipy.signal import freqresp

        hz = np.atleast_1d(np.asarray(hz, dtype=float))
        if sampled:
            diagonal = np.stack([loop.freqresp(2.0 * math.pi * hz * self.dt)[1]
                                 for loop in self.discrete_closed_loops()], axis=-1)
        else:
            diagonal = np.stack([freqresp(loop, 2.0 * math.pi * hz)[1] for loop in self.closed_loops()], axis=-1)
        legs = np.einsum("ij,nj,kj->nik", self.modes, diagonal, self.modes)
        jacobian = self.table.leg_jacobian(self._lin_pose)
        return np.linalg.solve(jacobian, legs @ jacobian)

    # ----- the interface of sim_table.actuators.Actuators ---------------------------------------------

    def step(self, reference: np.ndarray, braked: np.ndarray) -> ActuatorStep:
        """Run k ticks: ``reference`` (k, 6) poses, ``braked`` (k,) whether the drives are braked at each."""
        reference = np.asarray(reference, dtype=float)
        braked = np.asarray(braked, dtype=bool)
        moved = np.abs(self.pose - self._lin_pose)
        if moved[:3].max() > RELINEARISE_M or moved[3:].max() > RELINEARISE_RAD:
            self.linearise(self.pose)
        clipped = np.clip(reference, -self._bound, self._bound)
        setpoint_limited = not np.array_equal(clipped, reference)
        g = self.table.geometry
        wanted = self.table.leg_lengths(clipped)
        commanded = np.clip(wanted, g.leg_min, g.leg_max)
        stroke_limited = not np.array_equal(commanded, wanted)
        out, saturated = self._advance(commanded, braked)
        ahead = np.arange(1, len(clipped) + 1)[:, None]
        guess = np.where(braked[:, None], self.pose, clipped + self._offset + self._drift * ahead)
        poses = self._kinematics.poses(out, guess)
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
        saturated = _run(self.modes, self._ad, self._bd, self._state, self._last_ref, self._last_w, commanded,
                         braked, self.stalled, self.dynamics.loop_gain, self.dynamics.velocity_feedforward, self.dt,
                         g.leg_speed, self.settings.brake_deceleration * self.dt, g.leg_min, g.leg_max, out)
        return out, bool(saturated)

    def measure(self, lengths: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The measured poses (..., 6): forward kinematics of the leg ``lengths`` (..., 6) read with noise, from
        ``pose`` (..., 6); several at once read the noise as one after the other would."""
        lengths = np.asarray(lengths, dtype=float)
        readings = (lengths + self._rng.normal(0.0, self.settings.noise, lengths.shape) if self.settings.noise
                    else lengths)
        return self._kinematics.poses(readings, pose)


def make_actuators(kind: str, table: TableModel, dt: float, settings: ActuatorSettings, *, payload: float = 0.0,
                   loads: Sequence[PlateLoad] = (), pose: np.ndarray | None = None,
                   seed: int = 0) -> Actuators | ServoActuators:
    """The emulator's legs of model ``kind`` (:data:`DYNAMICS`) at rest at ``pose`` (default home); ``loads``: the
    specimens as rigid masses at their places (:func:`specimen_loads`), ``payload``: a mass [kg] at the plate's
    centre (the lag legs carry no mass)."""
    if kind == "lag":
        return Actuators(table, dt, settings, pose=pose, seed=seed)
    if kind == "servo":
        return ServoActuators(table, dt, settings, payload=payload, loads=loads, pose=pose, seed=seed)
    raise ValueError(f"unknown dynamics {kind!r}: expected one of {', '.join(DYNAMICS)}")
