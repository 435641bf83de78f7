"""The physical specimens of the emulated table: bodies standing on the moving plate, and their overturns.

:class:`SpecimenScene` runs the MuJoCo model of :mod:`sim_table.scene` with the plate following the achieved plate
pose. Poses are ``(surge, sway, heave, roll, pitch, yaw)`` [m, rad] with ``R = Rz(yaw) Ry(pitch) Rx(roll)``
(``analysis.table.model``); plate velocities are the pose rates [m/s, rad/s] in the same column order. Between two
samples the plate follows the cubic Hermite curve through their poses and rates; feed it the plate's true, smooth
state, not noisy measurements (the bodies feel the curve's second difference).

A body's **angle** θ [rad] is its rotation about the plate's y axis relative to the plate, > 0 when its top has
moved towards the plate's +x (downhill). A body has **overturned** when ``|θ| ≥ min(α + overturn_margin, π/2 −
0.05)`` (α its slenderness towards the side it leans to, ``overturn_margin`` default :data:`OVERTURN_MARGIN` rad),
direction ``sign(θ)``: +1 towards +x (the low side), −1 towards the high side; reported once per placement. A body
with a :attr:`~sim_table.scene.Specimen.restitution` e has every impact scaled to it (after a lean of at least
:data:`IMPACT_LEAN` rad). :attr:`~SpecimenScene.sample_angles` holds θ of every body at each plate sample time
given to :meth:`advance` or :meth:`~SpecimenScene.advance_many` (the tilt sensors).

How the plate's path is stepped, why the overturn threshold is where it is, the impact model: docs/specimens.md §The
scene.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np
from mujoco import rollout
from numpy.typing import NDArray

from analysis.table.model import rotation_matrices
from sim_table.plate_path import load as load_plate_path
from sim_table.plate_path import plate_steps
from sim_table.scene import PLATE_ARMATURE, PLATE_QPOS_ORDER, ContactSettings, Specimen, SpecimenError, build_model
from sim_table.tick_profile import TickProfile

Pose = Sequence[float] | NDArray[np.float64]
"""A plate pose (surge, sway, heave [m], roll, pitch, yaw [rad]) or its velocity [m/s, rad/s], (6,)."""

OVERTURN_MARGIN = 0.8
"""Default rotation past the slenderness angle α at which a body counts as overturned [rad]."""

IMPACT_LEAN = 1.0e-3
"""|θ| [rad] a body must have reached since its last impact for its next passage through θ = 0 to count as an
impact (the impact model, module docstring)."""

LYING = 0.5 * math.pi - 0.05
"""Cap of the overturn threshold [rad]: a body within 0.05 rad of lying on its side has overturned."""


_CONTROL = mujoco.mjtState.mjSTATE_QFRC_APPLIED.value
"""What a rollout's controls are: each step's generalised applied force (nv,)."""


class Overturn(NamedTuple):
    """One detected overturn: time [s], index of the specimen, direction (+1 low side / −1 high side)."""

    t: float
    body_id: int
    direction: int


class SpecimenScene:
    """Specimens standing on a plate driven by the achieved plate pose.

    The ``specimens`` stand upright and at rest at their places on the plate, which is still at
    ``plate_pose`` (6,) (default home); the scene's clock starts at 0 s. ``contact`` sets the physics step
    and contact model, ``overturn_margin`` [rad] the detection threshold (module docstring). ``model`` and
    ``data`` are the MuJoCo model and state, for viewers and diagnostics: step the scene only through
    :meth:`advance`. ``profile``: where :meth:`advance_many` laps its stages (``physics``, ``impacts``,
    ``specimens``: ``sim_table.tick_profile``), if given.
    """

    def __init__(self, specimens: Sequence[Specimen], *, plate_pose: Pose | None = None,
                 contact: ContactSettings | None = None, overturn_margin: float = OVERTURN_MARGIN,
                 profile: TickProfile | None = None) -> None:
        if not (math.isfinite(overturn_margin) and overturn_margin > 0):
            raise SpecimenError(f"overturn_margin must be > 0 rad, got {overturn_margin!r}")
        self.specimens = tuple(specimens)
        self._profile = profile
        self.contact = contact or ContactSettings()
        self.model = build_model(self.specimens, self.contact)
        self.data = mujoco.MjData(self.model)
        self.thresholds = np.array([[min(s.body.alpha_plus + overturn_margin, LYING),
                                     min(s.body.alpha_minus + overturn_margin, LYING)] for s in self.specimens])
        """|θ| at which each specimen counts as overturned [rad], (n, 2): leaning towards +x (column 0) or −x."""
        self._order = np.array(PLATE_QPOS_ORDER)
        self._state_size = mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self._roller = rollout.Rollout(nthread=0)
        """``mujoco.rollout`` on this thread, kept: each batch's call skips the wrapper's checks and allocations
        (the arrays are made to its shapes here), the same C rollout."""
        load_plate_path()  # compiled (or loaded) now, not in the first batch
        self._plate = self.model.body("plate").id
        self._bodies = np.array([self.model.body(f"specimen{i}").id for i in range(len(self.specimens))])
        self._sample = (0.0, np.zeros(6), np.zeros(6))
        self._plate_rate = np.zeros(6)
        self._detections: list[Overturn] = []
        self._standing = np.ones(len(self.specimens), dtype=bool)
        self._theta = np.zeros(len(self.specimens))
        self._impacts = _Impacts(self.specimens)
        joints = self.model.body_jntadr[self._bodies]
        self._dofs = self.model.jnt_dofadr[joints]
        """First degree of freedom of each specimen's free joint (linear velocity, then angular in its frame)."""
        self.sample_angles = np.zeros((0, len(self.specimens)))
        """θ of every specimen [rad] (> 0: its top moved towards the plate's +x) at each time of the last
        :meth:`advance` (1, n) or :meth:`advance_many` (k, n): the state of the physics step that ended within half
        a step of it (an interval too short for a step repeats the angles before it). Empty (0, n) after
        :meth:`place`."""
        self.place(np.zeros(6) if plate_pose is None else plate_pose)

    @property
    def time(self) -> float:
        """The scene's clock [s]: the end of the last physics step."""
        return self.data.time

    def place(self, plate_pose: Pose | None = None, leans: Sequence[float] | None = None) -> None:
        """Put every specimen back at its place, at rest, and re-arm overturn detection.

        This is the operator placing the bodies: the plate is held still at ``plate_pose`` (6,) (default:
        the last pose it was given), and the next :meth:`advance` starts from there. ``leans`` [rad], one
        per specimen, stands a body on a base edge at θ = lean (> 0: on its +x edge) instead of upright,
        released at rest (free-rocking tests); 0 = upright.
        """
        pose = self._sample[1] if plate_pose is None else _as_pose(plate_pose, "plate_pose")
        n = len(self.specimens)
        lean = np.zeros(n) if leans is None else np.asarray(leans, dtype=float)
        if lean.shape != (n,) or not np.all(np.abs(lean) < 0.5 * math.pi):
            raise SpecimenError(f"leans: need {n} angles within (-pi/2, pi/2) rad, got {leans!r}")
        self._sample = (self.time, pose, np.zeros(6))
        self._plate_rate = np.zeros(6)
        d = self.data
        d.qpos[:6] = pose[self._order]
        d.qvel[:] = 0.0
        plate_rotation = rotation_matrices(pose)
        quat = np.empty(4)
        for i, (s, th) in enumerate(zip(self.specimens, lean, strict=True)):
            side = math.copysign(0.5 * s.body.b, th) if th else 0.0
            tilt = rotation_matrices(np.array([0.0, 0.0, 0.0, 0.0, th, 0.0]))
            centre = np.array([s.x + side, s.y, 0.0]) + tilt @ np.array([-side, 0.0, 0.5 * s.body.h])
            d.qpos[6 + 7 * i: 9 + 7 * i] = pose[:3] + plate_rotation @ centre
            mujoco.mju_mat2Quat(quat, (plate_rotation @ tilt).ravel())
            d.qpos[9 + 7 * i: 13 + 7 * i] = quat
        mujoco.mj_forward(self.model, d)
        self._detections = []
        self._standing[:] = True
        self._theta = self.specimen_angles()
        self._impacts.reset(self._theta)
        self.sample_angles = np.zeros((0, n))

    def advance(self, t: float, plate_pose: Pose, plate_velocity: Pose) -> list[Overturn]:
        """Step the physics to time ``t`` [s], where the plate has ``plate_pose`` and ``plate_velocity`` (6,).

        Returns the overturns detected in this interval (also kept for :meth:`detections`); the bodies' angles at
        ``t`` are :attr:`sample_angles` (1, n). The clock moves in whole physics steps and stops within half a step
        of ``t``.
        """
        t0, pose0, vel0 = self._sample
        if not t > t0:
            raise SpecimenError(f"advance: time must increase, got {t!r} s after {t0!r} s")
        pose1, vel1 = _as_pose(plate_pose, "plate_pose"), _as_pose(plate_velocity, "plate_velocity")
        span = t - t0
        path = _hermite(pose0[self._order], span * vel0[self._order], pose1[self._order], span * vel1[self._order])
        m, d, dt = self.model, self.data, self.model.opt.timestep
        here = _evaluate(path, (d.time - t0) / span)
        found: list[Overturn] = []
        while d.time + 0.5 * dt <= t:
            there = _evaluate(path, (d.time + dt - t0) / span)
            rate = (there - here) / dt
            d.qpos[:6] = here
            d.qvel[:6] = self._plate_rate
            d.qfrc_applied[:6] = (PLATE_ARMATURE / dt) * (rate - self._plate_rate)
            mujoco.mj_step(m, d)
            mujoco.mj_kinematics(m, d)
            here, self._plate_rate = there, rate
            if not (self._impacts.active or self._standing.any()):
                continue
            theta = self.specimen_angles()[None, :]  # read once a step: the impact scaling moves no body
            if self._impacts.active:
                hit = self._impacts.first(theta, self._standing)
                if hit is not None:
                    self._restitute(hit[1], hit[2])
            if self._standing.any():
                found.extend(self._detect_steps(np.array([d.time]), theta, dt))
                self._theta = theta[0]
        self._sample = (t, pose1, vel1)
        self._detections.extend(found)
        self.sample_angles = self.specimen_angles()[None, :]
        return found

    def advance_many(self, times: np.ndarray, plate_poses: np.ndarray, plate_velocities: np.ndarray) -> list[Overturn]:
        """:meth:`advance` through ``times`` (k,) [s, increasing] where the plate has ``plate_poses`` and
        ``plate_velocities`` (k, 6), with the physics of the whole batch stepped in C (``mujoco.rollout``).

        The plate follows the same Hermite curves through the samples, step by step: its joints are put on the
        curve once, at the batch's start, and each step's generalised force armature × acceleration (what
        :meth:`advance` applies after putting them back on the curve) keeps them there — the bodies' reactions
        (impacts too) move a plate of :data:`~sim_table.scene.PLATE_ARMATURE` by < 1e-6 m over hundreds of
        steps. The bodies' angles are read from each step's state, overturns detected and timed as
        :meth:`advance` does, and the angles at ``times`` kept in :attr:`sample_angles` (k, n).
        """
        times = np.asarray(times, dtype=float)
        poses, rates = np.asarray(plate_poses, dtype=float), np.asarray(plate_velocities, dtype=float)
        k = len(times)
        if times.shape != (k,) or poses.shape != (k, 6) or rates.shape != (k, 6) or not (
                np.all(np.isfinite(times)) and np.all(np.isfinite(poses)) and np.all(np.isfinite(rates))):
            raise SpecimenError(f"advance_many: need finite times (k,), poses and velocities (k, 6), got "
                                f"{times.shape}, {poses.shape}, {rates.shape}")
        t0, pose0, vel0 = self._sample
        if k == 0:
            self.sample_angles = np.zeros((0, len(self.specimens)))
            return []
        if not (times[0] > t0 and np.all(np.diff(times) > 0)):
            raise SpecimenError(f"advance_many: times must increase, got {times[0]!r} s after {t0!r} s …")
        m, d, dt = self.model, self.data, self.model.opt.timestep
        # the physics steps of each interval, as advance() takes them: each step's start (the clock advanced by
        # dt, step after step, as advance() advances it) in the first interval whose end is at least half a step
        # on; the plate on the Hermite curve of its interval (sim_table.plate_path)
        count = max(0, math.ceil((times[-1] - d.time) / dt) + 2)
        interval, here, force, last_rate = plate_steps(times, poses, rates, t0, pose0, vel0, d.time, dt, count,
                                                       self._order, self._plate_rate, PLATE_ARMATURE / dt, m.nv)
        found: list[Overturn] = []
        angles = self.specimen_angles()[None, :]  # before the batch, then after each step
        if len(interval):
            d.qpos[:6] = here
            d.qvel[:6] = self._plate_rate
            self._lap("specimens")
            states, step_angles = self._rollout(force)
            self._plate_rate = last_rate
            if self._standing.any():
                found = self._detect_steps(states[:, 0], step_angles, dt)
            self._theta = self.specimen_angles()
            self._lap("impacts")
            angles = np.vstack([angles, step_angles])
        # each sample time's angles: those after the last step of its interval (row 0: before the batch)
        self.sample_angles = angles[np.searchsorted(interval, np.arange(k), side="right")]
        self._sample = (float(times[-1]), poses[-1].copy(), rates[-1].copy())
        self._detections.extend(found)
        return found

    def _rollout(self, force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Step the physics from :attr:`data` once per row of generalised ``force`` (steps, nv) in C; the states
        after each step (steps, FULLPHYSICS size) and the bodies' angles (steps, n), :attr:`data` left after the
        last. A batch with an impact of a body whose restitution is set (module docstring) is cut after that
        step, the impact scaled, and the rest of the batch stepped from there."""
        m, d = self.model, self.data
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.empty((1, self._state_size))
        parts, angle_parts = [], []
        start = 0
        while start < len(force):
            mujoco.mj_getState(m, d, state[0], spec)
            steps = len(force) - start
            rolled = np.empty((1, steps, self._state_size))
            self._roller.rollout([m], [d], state, np.ascontiguousarray(force[None, start:]), control_spec=_CONTROL,
                                 skip_checks=True, nstep=steps, initial_warmstart=d.qacc_warmstart.copy()[None],
                                 state=rolled, sensordata=np.empty((1, steps, m.nsensordata)))
            states = rolled[0]
            self._lap("physics")
            angles = _specimen_angles(states[:, 1:1 + m.nq], len(self.specimens))
            hit = self._impacts.first(angles, self._standing) if self._impacts.active else None
            if hit is None:
                self._lap("impacts")
                mujoco.mj_kinematics(m, d)
                self._lap("physics")
                parts.append(states)
                angle_parts.append(angles)
                break
            step, bodies, sides = hit
            mujoco.mj_setState(m, d, states[step], spec)
            self._restitute(bodies, sides)
            mujoco.mj_getState(m, d, states[step], spec)
            self._lap("impacts")
            parts.append(states[:step + 1])
            angle_parts.append(angles[:step + 1])
            start += step + 1
        return np.vstack(parts), np.vstack(angle_parts)

    def _lap(self, stage: str) -> None:
        """The CPU time since the profile's last lap was spent in ``stage`` (when profiled)."""
        if self._profile is not None:
            self._profile.lap(stage)

    def _restitute(self, bodies: np.ndarray, sides: np.ndarray) -> None:
        """Scale the velocity relative to the plate of each of ``bodies`` (indices) by its impact factor
        (module docstring) for an impact ending its rocking on the corner ``sides`` (±1, one per body), in
        :attr:`data`, and bring the derived quantities up to date."""
        m, d = self.model, self.data
        mujoco.mj_forward(m, d)
        plate = np.empty(6)  # angular, then linear velocity of the plate's origin, world frame
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._plate, plate, 0)
        for i, side in zip(bodies, sides, strict=True):
            k, body, dof = self._impacts.factor[i, 0 if side > 0 else 1], self._bodies[i], self._dofs[i]
            rotation = d.xmat[body].reshape(3, 3)
            carried = plate[3:] + np.cross(plate[:3], d.xpos[body] - d.xpos[self._plate])
            spin = rotation @ d.qvel[dof + 3:dof + 6]
            d.qvel[dof:dof + 3] = carried + k * (d.qvel[dof:dof + 3] - carried)
            d.qvel[dof + 3:dof + 6] = rotation.T @ (plate[:3] + k * (spin - plate[:3]))
        mujoco.mj_forward(m, d)

    def _detect_steps(self, step_times: np.ndarray, angles: np.ndarray, dt: float) -> list[Overturn]:
        """Overturns in the steps just taken, which ended at ``step_times`` (steps,) [s] with the bodies at ``angles``
        (steps, n) [rad], timed by linear interpolation of |θ| within the step that crossed the threshold."""
        threshold = np.where(angles >= 0.0, self.thresholds[:, 0], self.thresholds[:, 1])  # (steps, n)
        over = (np.abs(angles) >= threshold) & self._standing  # all steps at once; each body's first one counts
        events = []
        for i in np.flatnonzero(over.any(axis=0)):
            step = int(np.argmax(over[:, i]))
            theta = angles[step, i]
            a0 = abs(self._theta[i] if step == 0 else angles[step - 1, i])
            a1 = abs(theta)
            fraction = min(1.0, max(0.0, (threshold[step, i] - a0) / (a1 - a0))) if a1 > a0 else 1.0
            events.append(Overturn(step_times[step] - (1.0 - fraction) * dt, int(i), 1 if theta > 0 else -1))
            self._standing[i] = False
        return sorted(events)

    def specimen_angles(self) -> np.ndarray:
        """θ of each specimen relative to the plate, (n,) [rad]: + when its top has moved towards +x."""
        xmat = self.data.xmat
        local = xmat[self._bodies][:, 2::3] @ xmat[self._plate].reshape(3, 3)
        return np.arctan2(local[:, 0], local[:, 2])

    def specimen_places(self) -> np.ndarray:
        """Point of the plate under each specimen's centre of mass, (n, 2) [m, plate frame x, y]."""
        d = self.data
        local = (d.xipos[self._bodies] - d.xpos[self._plate]) @ d.xmat[self._plate].reshape(3, 3)
        return local[:, :2]

    def detections(self) -> list[Overturn]:
        """Every overturn since the last placement, in time order, each specimen at most once."""
        return list(self._detections)


class _Impacts:
    """The rocking impacts of the bodies whose restitution is set (the impact model, module docstring)."""

    def __init__(self, specimens: Sequence[Specimen]) -> None:
        self.factor = np.array([(math.nan, math.nan) if s.restitution is None else
                                tuple(s.restitution / e for e in s.housner_restitutions) for s in specimens]
                               ).reshape(len(specimens), 2)
        """Velocity factor of each body's impacts, (n, 2): restitution / Housner's of an impact ending its rocking on
        the +x corner (column 0), on the −x corner (column 1); NaN: the contact's own."""
        self.bodies = np.flatnonzero(np.isfinite(self.factor[:, 0]))
        self.active = bool(self.bodies.size)
        self._side = np.zeros(self.bodies.size)
        self._lean = np.zeros(self.bodies.size)

    def reset(self, angles: np.ndarray) -> None:
        """The bodies placed at ``angles`` (n,) [rad]: no impact counted yet."""
        self._side = np.sign(angles[self.bodies])
        self._lean = np.abs(angles[self.bodies])

    def first(self, angles: np.ndarray, standing: np.ndarray) -> tuple[int, np.ndarray, np.ndarray] | None:
        """Follow the bodies through the steps' ``angles`` (steps, n) [rad] up to the first step at which a standing
        body impacts; (that step, the indices of the bodies impacting in it, the corner each was rocking on: ±1),
        or None after the last step."""
        theta = angles[:, self.bodies]
        steps = len(theta)
        side = np.sign(theta)
        # the side each step leaves a body on (a step exactly at θ = 0 keeps the one before), row 0: before them
        known = np.vstack([np.ones((1, theta.shape[1]), dtype=bool), side != 0])
        last = np.maximum.accumulate(np.where(known, np.arange(steps + 1)[:, None], 0), axis=0)
        sides = np.take_along_axis(np.vstack([self._side[None, :], side]), last, axis=0)
        crossed = (side != 0) & (side != sides[:-1])
        # the largest |θ| since the last crossing (a crossing step starts afresh with its own |θ|), row 0: before:
        # a running maximum that restarts at each crossing, by lifting each stretch above the ones before it
        # (|θ| < π/2 < 2 per stretch)
        stretch = np.vstack([np.zeros((1, theta.shape[1])), np.cumsum(crossed, axis=0)])
        lifted = np.vstack([self._lean[None, :], np.abs(theta)]) + 2.0 * stretch
        lean = np.maximum.accumulate(lifted, axis=0) - 2.0 * stretch
        hit = crossed & (sides[:-1] != 0) & (lean[:-1] >= IMPACT_LEAN) & standing[self.bodies]
        rows = np.flatnonzero(hit.any(axis=1))
        at = int(rows[0]) if rows.size else steps - 1
        before = sides[at]  # the side each body was on before this step: the corner the impact ends rocking on
        self._side, self._lean = sides[at + 1], lean[at + 1]
        return (at, self.bodies[hit[at]], before[hit[at]]) if rows.size else None


def _specimen_angles(qpos: np.ndarray, count: int) -> np.ndarray:
    """θ of ``count`` specimens (steps, count) [rad] from plate and free-joint positions ``qpos`` (steps, nq), as
    :meth:`SpecimenScene.specimen_angles` reads them from the kinematics: each body's height axis (its
    quaternion's rotation, third column) in the plate frame, ``atan2(ex, ez)``."""
    plate = rotation_matrices(qpos[:, list(PLATE_QPOS_ORDER)])  # (steps, 3, 3): qpos order is its own inverse
    quat = qpos[:, 6:6 + 7 * count].reshape(len(qpos), count, 7)[:, :, 3:]  # free joints: position, quaternion
    quat = quat / np.linalg.norm(quat, axis=2, keepdims=True)
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    axis = np.stack([2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)], axis=2)
    local = np.einsum("sji,snj->sni", plate, axis)  # Rᵀ e in the plate frame
    return np.arctan2(local[..., 0], local[..., 2])


def _hermite(p0: np.ndarray, m0: np.ndarray, p1: np.ndarray, m1: np.ndarray) -> tuple[np.ndarray, ...]:
    """Coefficients (c3, c2, c1, c0) of the cubic through values p0, p1 with slopes m0, m1 (per unit u)."""
    return 2.0 * (p0 - p1) + m0 + m1, 3.0 * (p1 - p0) - 2.0 * m0 - m1, m0, p0


def _evaluate(coefficients: Sequence[np.ndarray], u: float | np.ndarray) -> np.ndarray:
    """The cubic of :func:`_hermite` at u (u = 0 at the interval's start, 1 at its end; arrays broadcast)."""
    c3, c2, c1, c0 = coefficients
    return ((c3 * u + c2) * u + c1) * u + c0


def _as_pose(values: Pose, name: str) -> np.ndarray:
    """A finite (6,) float array, or :class:`SpecimenError`."""
    array = np.asarray(values, dtype=float)
    if array.shape != (6,) or not np.all(np.isfinite(array)):
        raise SpecimenError(f"{name}: need 6 finite values (surge, sway, heave, roll, pitch, yaw), got {values!r}")
    return array
