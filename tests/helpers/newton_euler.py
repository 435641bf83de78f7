"""An independent Newton–Euler solve of a block on a corner, the truth the stage equations are tested against
(``test_general.py`` for centred blocks, ``test_asymmetric.py`` for off-centre centres of mass)."""

from __future__ import annotations

import math

import numpy as np

from analysis.body import Body


def rot(theta: float) -> np.ndarray:
    """Clockwise rotation by θ (θ > 0 tips the block towards +x)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s], [-s, c]])


def centre_from_pivot(body: Body, s: float) -> np.ndarray:
    """The centre of mass from the pivot corner s (+1: the +x corner) with the block upright: (−s d_s, h_cg), d_s its
    horizontal distance from that corner (b − b_cg for +, b_cg for −)."""
    return np.array([-s * (body.d_plus if s > 0 else body.d_minus), body.cg[1]])


def newton_euler(theta: float, omega: float, s: float, gx: float, gz: float, body: Body,
                 slip: float | None = None, mu: float = 0.0) -> np.ndarray:
    """(θ'', pivot acceleration, R_t, R_n) per unit mass; ``slip`` None: the pivot sticks.

    Geometry from rotation matrices: the centre of mass sits at d = Rot(θ)·d0 from the pivot, d0
    :func:`centre_from_pivot`; d'' = θ'' Rot'(θ)·d0 + θ'² Rot''(θ)·d0. Newton: x_p'' e_x + d'' = (gx, −gz) + R.
    Euler about the centre of mass (counter-clockwise positive, θ is clockwise): −i_g² θ'' = (−d) × R.
    """
    d0 = centre_from_pivot(body, s)
    c, sn = math.cos(theta), math.sin(theta)
    d = rot(theta) @ d0
    d1 = np.array([[-sn, c], [-c, -sn]]) @ d0  # dRot/dθ · d0
    d2 = np.array([[-c, -sn], [sn, -c]]) @ d0  # d²Rot/dθ² · d0
    # unknowns u = (θ'', xp'', Rt, Rn)
    a = np.zeros((4, 4))
    rhs = np.zeros(4)
    a[0] = [d1[0], 1.0, -1.0, 0.0]
    rhs[0] = gx - omega**2 * d2[0]
    a[1] = [d1[1], 0.0, 0.0, -1.0]
    rhs[1] = -gz - omega**2 * d2[1]
    a[2] = [body.i_g**2, 0.0, d[1], -d[0]]  # −i_g² θ'' = (−d)_x R_n − (−d)_z R_t
    a[3] = [0.0, 1.0, 0.0, 0.0] if slip is None else [0.0, 0.0, 1.0, mu * slip]
    return np.linalg.solve(a, rhs)
