"""The emulator's forward kinematics compiled: a batch of leg lengths → plate poses in one numba pass.

The same Newton method as ``TableModel.pose_from_leg_lengths`` (the six inverse-kinematics residuals, the analytic
leg Jacobian of ``analysis.table.kinematics``, from a guess, until every leg-length residual is ≤ ``tol`` [m]),
pose by pose instead of all poses together: each pose stops at its own convergence, so the answers agree with
``TableModel``'s to within the tolerance (1e-12 m: rounding), not bit for bit. A pose that does not converge, or
meets a singular Jacobian, sends the whole batch to ``TableModel.pose_from_leg_lengths``, which solves it or says
why it cannot (``TableModelError``).

Poses ``(surge, sway, heave [m], roll, pitch, yaw [rad])``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; leg lengths [m]
joint to joint, legs in ``HexapodGeometry``'s order.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.compiled_index import njit
from analysis.table.model import TableModel


class ForwardKinematics:
    """Forward kinematics of one ``table`` (module docstring)."""

    def __init__(self, table: TableModel) -> None:
        self.table = table
        g = table.geometry
        self._joints = np.ascontiguousarray(np.stack([g.base_joints, g.platform_joints]), dtype=np.float64)
        self._home_height = float(g.home_height)
        self.poses(table.leg_lengths(np.zeros((1, 6))), np.zeros((1, 6)))  # compile (or load) now, not mid-stream

    def poses(self, lengths: np.ndarray, guess: np.ndarray, *, tol: float = 1e-12, max_iter: int = 50
              ) -> np.ndarray:
        """The poses (..., 6) whose legs have ``lengths`` (..., 6) [m], by Newton from ``guess`` (broadcast to
        them) (module docstring)."""
        lengths = np.asarray(lengths, dtype=np.float64)
        if lengths.ndim == 0 or lengths.shape[-1] != 6:
            return self.table.pose_from_leg_lengths(lengths, guess=guess, tol=tol, max_iter=max_iter)
        flat = np.ascontiguousarray(lengths.reshape(-1, 6))
        start = np.ascontiguousarray(np.broadcast_to(guess, lengths.shape).reshape(-1, 6), dtype=np.float64)
        out = np.empty_like(flat)
        if _solve(flat, start, self._joints, self._home_height, tol, max_iter, out):
            return out.reshape(lengths.shape)
        return self.table.pose_from_leg_lengths(lengths, guess=guess, tol=tol, max_iter=max_iter)


@njit(cache=True)
def _solve(lengths: np.ndarray, guess: np.ndarray, joints: np.ndarray, home_height: float, tol: float,
           max_iter: int, out: np.ndarray) -> bool:
    """Newton pose by pose into ``out`` (k, 6); False when one does not converge or meets a singular Jacobian."""
    base, platform = joints[0], joints[1]
    jacobian = np.empty((6, 6))
    residual = np.empty(6)
    for i in range(lengths.shape[0]):
        if not np.all(lengths[i] > 0.0):
            return False
        x = guess[i].copy()
        for iteration in range(max_iter + 1):
            cr, cp, cy = math.cos(x[3]), math.cos(x[4]), math.cos(x[5])
            sr, sp, sy = math.sin(x[3]), math.sin(x[4]), math.sin(x[5])
            r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
            r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
            r20, r21, r22 = -sp, cp * sr, cp * cr
            worst = 0.0
            for k in range(6):
                qx, qy, qz = platform[k, 0], platform[k, 1], platform[k, 2]
                rx = r00 * qx + r01 * qy + r02 * qz
                ry = r10 * qx + r11 * qy + r12 * qz
                rz = r20 * qx + r21 * qy + r22 * qz
                dx = rx + (x[0] - base[k, 0])
                dy = ry + (x[1] - base[k, 1])
                dz = rz + (x[2] + home_height - base[k, 2])
                length = math.sqrt(dx * dx + dy * dy + dz * dz)
                residual[k] = length - lengths[i, k]
                worst = max(worst, abs(residual[k]))
                ux, uy, uz = dx / length, dy / length, dz / length
                cx, cy_, cz = ry * uz - rz * uy, rz * ux - rx * uz, rx * uy - ry * ux  # R q × u
                jacobian[k, 0], jacobian[k, 1], jacobian[k, 2] = ux, uy, uz
                jacobian[k, 3] = cx * r00 + cy_ * r10 + cz * r20  # roll: about R [1, 0, 0]
                jacobian[k, 4] = -cx * sy + cy_ * cy  # pitch: about Rz(yaw) [0, 1, 0]
                jacobian[k, 5] = cz  # yaw: about [0, 0, 1]
            if not math.isfinite(worst):
                return False
            if worst <= tol:
                break
            if iteration == max_iter:
                return False
            if not _eliminate(jacobian, residual):
                return False
            x -= residual
        out[i] = x
    return True


@njit(cache=True)
def _eliminate(a: np.ndarray, b: np.ndarray) -> bool:
    """Solve ``a x = b`` (6 × 6) in place by Gaussian elimination with partial pivoting: ``x`` left in ``b``,
    ``a`` overwritten; False when ``a`` is singular."""
    n = a.shape[0]
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if a[pivot, col] == 0.0:
            return False
        if pivot != col:
            for j in range(n):
                a[col, j], a[pivot, j] = a[pivot, j], a[col, j]
            b[col], b[pivot] = b[pivot], b[col]
        for row in range(col + 1, n):
            factor = a[row, col] / a[col, col]
            for j in range(col, n):
                a[row, j] -= factor * a[col, j]
            b[row] -= factor * b[col]
    for row in range(n - 1, -1, -1):
        total = b[row]
        for j in range(row + 1, n):
            total -= a[row, j] * b[j]
        b[row] = total / a[row, row]
    return True
