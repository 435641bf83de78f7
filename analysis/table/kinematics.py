"""The hexapod's geometry and kinematics: rotations, leg vectors, lengths, their Jacobian and rates.

Frames and units (docs/architecture.md §2). SI inside: m, s, rad. The base (world) frame has x = surge,
y = sway (lateral, to the left of +x), z = heave, **z up**, right-handed. A pose is a float array
``(..., 6)``: ``surge, sway, heave`` [m], the displacement of the platform frame from its home pose, and
``roll, pitch, yaw`` [rad], its orientation ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (intrinsic Z-Y'-X'');
this is the column order of the session file's ``commanded`` dataset after its time column. The platform
frame's origin is the centre of the plate's top surface; at home it sits ``home_height`` above the base
frame's origin with the axes parallel to the base frame's.

The plate tilt β > 0 of the study is **pitch = +β**: ``Ry(β)`` takes the plate's +x end down
(``Ry(β) @ [1, 0, 0] = [cos β, 0, −sin β]``), so the plate's +x points downhill and the desired overturn
direction +1 (towards the low side) is towards +x.

Legs are numbered 1..6 in messages (index 0..5 in arrays); leg k joins ``base_joints[k]`` (base frame)
to ``platform_joints[k]`` (platform frame), and its length is the joint-to-joint distance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from analysis.errors import AnalysisInputError
from analysis.table.limits import DEG, TableModelError, check_fields, half_angle, non_negative, number_problem, positive


def rotation_matrices(poses: np.ndarray) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` of each pose ``(..., 6)`` → ``(..., 3, 3)`` (platform → base)."""
    poses = np.asarray(poses, dtype=float)
    cos, sin = np.cos(poses[..., 3:6]), np.sin(poses[..., 3:6])
    cr, cp, cy = cos[..., 0], cos[..., 1], cos[..., 2]
    sr, sp, sy = sin[..., 0], sin[..., 1], sin[..., 2]
    R = np.empty((*poses.shape[:-1], 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sp, cp * sr, cp * cr
    return R


class Legs(NamedTuple):
    """The legs at poses ``(..., 6)``: vectors base joint → platform joint ``d`` ``(..., 6, 3)`` [m], the
    rotated platform joints ``rq = R q`` ``(..., 6, 3)`` [m] and the rotations ``R`` ``(..., 3, 3)``."""

    poses: np.ndarray
    d: np.ndarray
    rq: np.ndarray
    R: np.ndarray

    def lengths(self) -> np.ndarray:
        return np.sqrt(np.einsum("...i,...i->...", self.d, self.d))

    def jacobian(self) -> np.ndarray:
        """d(leg lengths)/d(pose) ``(..., 6, 6)``.

        Translation columns: the unit leg vector u. Rotation columns: ``dL/dθ = u · (ω_θ × R q) =
        (R q × u) · ω_θ`` where ω_θ is the angular velocity per unit rate of that Euler angle: roll →
        ``R [1, 0, 0]``, pitch → ``Rz(yaw) [0, 1, 0]``, yaw → ``[0, 0, 1]``.
        """
        u = self.d / self.lengths()[..., None]
        yaw = self.poses[..., 5]
        zeros, ones = np.zeros_like(yaw), np.ones_like(yaw)
        omega = np.stack([self.R[..., :, 0], np.stack([-np.sin(yaw), np.cos(yaw), zeros], -1),
                          np.stack([zeros, zeros, ones], -1)], axis=-2)  # (..., 3 angles, 3)
        return np.concatenate([u, np.einsum("...kj,...aj->...ka", np.cross(self.rq, u), omega)], axis=-1)

    def rates(self, pose_rates: np.ndarray, lengths: np.ndarray | None = None) -> np.ndarray:
        """d(leg lengths)/dt ``(..., 6)`` [m/s] for pose rates ``(..., 6)``: ``u · (v + ω × R q)``.

        The same numbers as ``jacobian() @ pose_rates`` without building the Jacobian (a long trajectory
        is checked in one pass). ω is the platform's angular velocity from the Euler angle rates (see
        `jacobian`).
        """
        lengths = self.lengths() if lengths is None else lengths
        yaw = self.poses[..., 5]
        omega = pose_rates[..., 3, None] * self.R[..., :, 0]
        omega[..., 0] -= pose_rates[..., 4] * np.sin(yaw)
        omega[..., 1] += pose_rates[..., 4] * np.cos(yaw)
        omega[..., 2] += pose_rates[..., 5]
        joint_velocity = np.cross(omega[..., None, :], self.rq)
        joint_velocity += pose_rates[..., None, :3]
        return np.einsum("...ki,...ki->...k", self.d, joint_velocity) / lengths


def legs_at(base: np.ndarray, platform: np.ndarray, home_height: float, poses: np.ndarray) -> Legs:
    """The legs of a hexapod at poses ``(..., 6)``."""
    R = rotation_matrices(poses)
    # R q for every pose and joint as three broadcast multiply-adds: no BLAS call, whose threads stall
    # when the machine's cores are busy (seen: 1 ms → 120 ms for 100k poses)
    columns = R[..., None, :, :]  # (..., 1, 3, 3)
    rq = columns[..., 0] * platform[:, 0, None] + columns[..., 1] * platform[:, 1, None] \
        + columns[..., 2] * platform[:, 2, None]
    origin = poses[..., :3] + np.array([0.0, 0.0, home_height])
    return Legs(poses, rq + (origin[..., None, :] - base), rq, R)


def geometry_problem(base: np.ndarray, platform: np.ndarray, home_height: float, leg_min: float, leg_max: float,
                      ) -> tuple[str, str] | None:
    """The first cross-field problem of a geometry as ``(field, message)``, else None."""
    if leg_min >= leg_max:
        return "leg_max", f"must exceed leg_min ({leg_min!r} m), got {leg_max!r} m"
    legs = legs_at(base, platform, home_height, np.zeros(6))
    lengths = legs.lengths()
    outside = np.flatnonzero((lengths < leg_min) | (lengths > leg_max))
    if outside.size:
        k = int(outside[0])
        return "home_height", (f"the home pose is outside the stroke: leg {k + 1} length {lengths[k]:.4f} m "
                               f"is not in [{leg_min:.4f}, {leg_max:.4f}] m")
    condition = np.linalg.cond(legs.jacobian())
    if not condition < 1e8:
        return "platform_joints", f"the legs are singular at home (Jacobian condition number {condition:.3g})"
    return None


@dataclass(frozen=True, eq=False)
class HexapodGeometry:
    """A 6-6 hexapod: joint centres, home height [m], leg length range [m] and leg speed [m/s].

    ``base_joints`` ``(6, 3)`` are in the base frame, ``platform_joints`` ``(6, 3)`` in the platform frame
    (origin at the centre of the plate's top surface); ``home_height`` is the height of the platform
    frame's origin above the base frame's origin at home. ``leg_min``/``leg_max`` bound each leg's
    joint-to-joint length, ``leg_speed`` its |d length/dt|. The arrays are stored as read-only copies.
    """

    base_joints: np.ndarray
    platform_joints: np.ndarray
    home_height: float
    leg_min: float
    leg_max: float
    leg_speed: float

    def __post_init__(self) -> None:
        for name in ("base_joints", "platform_joints"):
            try:
                joints = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise TableModelError(f"HexapodGeometry.{name}: expected 6 rows [x, y, z] in metres") from None
            if joints.shape != (6, 3) or not np.all(np.isfinite(joints)):
                raise TableModelError(f"HexapodGeometry.{name}: expected 6 finite rows [x, y, z] in metres, "
                                      f"got shape {joints.shape}")
            joints.setflags(write=False)
            object.__setattr__(self, name, joints)
        check_fields(self, positive, ("home_height", "leg_min", "leg_max", "leg_speed"))
        problem = geometry_problem(self.base_joints, self.platform_joints, self.home_height, self.leg_min,
                                    self.leg_max)
        if problem:
            raise TableModelError(f"HexapodGeometry.{problem[0]}: {problem[1]}")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, HexapodGeometry):
            return NotImplemented
        return (np.array_equal(self.base_joints, other.base_joints)
                and np.array_equal(self.platform_joints, other.platform_joints)
                and self._scalars() == other._scalars())

    def __hash__(self) -> int:
        return hash((tuple(self.base_joints.ravel().tolist()), tuple(self.platform_joints.ravel().tolist()),
                     self._scalars()))

    def _scalars(self) -> tuple[float, float, float, float]:
        return self.home_height, self.leg_min, self.leg_max, self.leg_speed

    @classmethod
    def default(cls) -> HexapodGeometry:
        """The rig's hexapod, sized so that Table IV's whole box combined with a 10° tilt is playable.

        Layout (:meth:`symmetric`): base joints on a 1.6 m radius circle, platform joints on a 1.1 m
        radius circle under a ~3 m plate, both in pairs at ±10° (platform pairs rotated by 60°), platform
        joint centres 0.15 m below the plate's top surface, home height 2.1 m (home leg length 2.208 m,
        the legs lean ~28° from vertical).

        Stroke: over the workspace |surge|, |sway| ≤ 0.25 m, |heave| ≤ 0.18 m, |roll|, |pitch| ≤ 10°,
        yaw 0, the legs span 1.6703 … 2.7798 m (the extremes are at corners of that box; found by
        sampling and local optimisation). leg_min = 1.60 m and leg_max = 2.85 m leave 0.070 m at both
        ends; stroke 1.25 m, retracted length 1.60 m = stroke + 0.35 m of cylinder and joints. The 10°
        tilt alone moves a platform joint by 1.1 sin 10° ≈ 0.19 m vertically, which is why the stroke
        is much larger than the ±0.18 m/±0.25 m of the box.

        Speed: a leg's rate is ``u · v + (R q × u) · ω`` (unit leg vector u). For any pose, with
        translational velocities inside Table IV (|v| ≤ √(0.5² + 0.5² + 0.3²) = 0.768 m/s) and roll and
        pitch rates both at 2°/s (|ω| = 0.049 rad/s, |R q| = 1.110 m) it is at most 0.768 + 0.055 =
        0.823 m/s; sampled over the workspace the worst leg needs 0.724 m/s. leg_speed = 0.9 m/s.
        """
        return cls.symmetric(base_radius=1.6, platform_radius=1.1, base_half_angle=10 * DEG,
                             platform_half_angle=10 * DEG, home_height=2.1, leg_min=1.6, leg_max=2.85,
                             leg_speed=0.9, platform_joint_depth=0.15)

    @classmethod
    def symmetric(cls, base_radius: float, platform_radius: float, base_half_angle: float,
                  platform_half_angle: float, home_height: float, leg_min: float, leg_max: float, leg_speed: float,
                  *, platform_joint_depth: float = 0.0) -> HexapodGeometry:
        """The classic 6-6 Stewart layout [m, rad].

        Base joints (z = 0) at radius ``base_radius`` and azimuths ``0° ∓ a, 120° ∓ a, 240° ∓ a``
        (``a = base_half_angle``); platform joints at radius ``platform_radius``, ``platform_joint_depth``
        below the plate's top surface (z = −depth in the platform frame), at ``60° ∓ b`` around
        ``−60°, 60°, 180°`` rotated so that leg k joins neighbouring joints: platform azimuths
        ``−60° + b, 60° − b, 60° + b, 180° − b, 180° + b, 300° − b`` (``b = platform_half_angle``).
        Half angles must be in [0, π/3). The layout is symmetric under rotations by 120° about z
        (leg k → k + 2) and under the mirror y → −y (legs 1↔2, 3↔6, 4↔5).
        """
        checks = ((positive, "base_radius", base_radius), (positive, "platform_radius", platform_radius),
                  (half_angle, "base_half_angle", base_half_angle),
                  (half_angle, "platform_half_angle", platform_half_angle),
                  (non_negative, "platform_joint_depth", platform_joint_depth))
        for check, name, value in checks:
            problem = number_problem(value, check)
            if problem:
                raise TableModelError(f"HexapodGeometry.symmetric: {name}: {problem}")
        base, platform = symmetric_joints(base_radius, platform_radius, base_half_angle, platform_half_angle,
                                           platform_joint_depth)
        return cls(base, platform, home_height, leg_min, leg_max, leg_speed)


def symmetric_joints(base_radius: float, platform_radius: float, base_half_angle: float,
                      platform_half_angle: float, platform_joint_depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Base and platform joints ``(6, 3)`` [m] of the layout described in :meth:`HexapodGeometry.symmetric`."""
    a, b = base_half_angle, platform_half_angle
    third = 2 * math.pi / 3
    base_azimuth = np.array([-a, a, third - a, third + a, 2 * third - a, 2 * third + a])
    platform_azimuth = np.array([-third / 2 + b, third / 2 - b, third / 2 + b, 1.5 * third - b, 1.5 * third + b,
                                 2.5 * third - b])
    base = np.stack([base_radius * np.cos(base_azimuth), base_radius * np.sin(base_azimuth), np.zeros(6)], -1)
    platform = np.stack([platform_radius * np.cos(platform_azimuth), platform_radius * np.sin(platform_azimuth),
                         np.full(6, -float(platform_joint_depth))], -1)
    return base, platform


def pose_array(values: np.ndarray, name: str) -> np.ndarray:
    """``values`` as a float array of poses ``(..., 6)``; `AnalysisInputError` naming ``name`` otherwise."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 0 or array.shape[-1] != 6:
        raise AnalysisInputError(f"{name}: expected an array of shape (..., 6), got shape {array.shape}")
    return array
