"""Cubic Hermite interpolation inside one integration step, for event location and extrema.

On a step of length H with end values (y0, v0) and (y1, v1) (value and derivative), the
interpolant in u = τ/H ∈ [0, 1] is c3 u³ + c2 u² + c1 u + c0; it is fourth-order accurate, like the
RK4 step it interpolates.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def coefficients(y0: float, v0: float, y1: float, v1: float, H: float) -> tuple[float, float, float, float]:
    """(c3, c2, c1, c0) of the interpolant in u = τ/H."""
    return (
        2.0 * y0 + H * v0 - 2.0 * y1 + H * v1,
        -3.0 * y0 - 2.0 * H * v0 + 3.0 * y1 - H * v1,
        H * v0,
        y0,
    )


@njit(cache=True, inline="always")
def value(c3: float, c2: float, c1: float, c0: float, u: float) -> float:
    """Interpolant at u."""
    return ((c3 * u + c2) * u + c1) * u + c0


@njit(cache=True)
def argmax_scaled(c3: float, c2: float, c1: float, c0: float, sign: float) -> float:
    """u ∈ [0, 1] where sign·interpolant is largest (endpoints or a stationary point)."""
    best_u = 0.0
    best = sign * c0
    v1 = sign * value(c3, c2, c1, c0, 1.0)
    if v1 > best:
        best, best_u = v1, 1.0
    a, b, c = 3.0 * c3, 2.0 * c2, c1
    if a == 0.0:
        if b != 0.0:
            u = -c / b
            if 0.0 < u < 1.0 and sign * value(c3, c2, c1, c0, u) > best:
                best_u = u
        return best_u
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return best_u
    sq = math.sqrt(disc)
    for u in ((-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a)):
        if 0.0 < u < 1.0:
            v = sign * value(c3, c2, c1, c0, u)
            if v > best:
                best, best_u = v, u
    return best_u


@njit(cache=True)
def crossing(c3: float, c2: float, c1: float, c0: float, sign: float, target: float, u_lo: float) -> float:
    """First u in (u_lo, 1] where sign·interpolant falls to / rises to ``target`` (bisection).

    Requires sign·y(u_lo) − target and sign·y(1) − target of opposite signs (or the latter zero).
    """
    f_lo = sign * value(c3, c2, c1, c0, u_lo) - target
    lo, hi = u_lo, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        f_mid = sign * value(c3, c2, c1, c0, mid) - target
        if (f_mid > 0.0) == (f_lo > 0.0) and f_mid != 0.0:
            lo, f_lo = mid, f_mid
        else:
            hi = mid
        if hi - lo < 1e-15:
            break
    return hi
