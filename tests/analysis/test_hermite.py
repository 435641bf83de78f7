"""The step interpolant's event location and extrema (``analysis.hermite``) against numpy's polynomial roots and a
dense evaluation: the first crossing in the interval (not just any), on its far side, to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from analysis import hermite


def _cubics(seed: int, n: int) -> list[tuple[float, float, float, float]]:
    """Step interpolants (c3, c2, c1, c0) as the engines make them: θ from a small angle down through 0 within a
    step of 0.3–30 ms, with end slopes that make one to three crossings."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        step = 10 ** rng.uniform(-3.5, -1.5)
        y0, v0 = 10 ** rng.uniform(-8, -2), -(10 ** rng.uniform(-3, 0.5))
        y1 = y0 - y0 / rng.uniform(0.01, 0.999)
        out.append(hermite.coefficients(y0, v0, y1, v0 * rng.uniform(0.8, 1.3), step))
    return out


def _rounding(c: tuple[float, float, float, float]) -> float:
    """A bound on the rounding of one evaluation of the cubic in [0, 1] (Horner's, with or without fused
    multiply-adds, which the compiled callers may differ in): a few units in the last place of its terms' sum."""
    return 8 * np.finfo(float).eps * sum(abs(x) for x in c)


def _first_root(c: tuple[float, float, float, float], lo: float) -> float:
    """The smallest real root in (lo, 1] of the cubic at which it changes sign, from its companion matrix."""
    roots = np.roots(c)
    real = np.sort(roots[(abs(roots.imag) < 1e-9) & (roots.real > lo) & (roots.real <= 1.0)].real)
    for r in real:
        if np.sign(hermite.value(*c, r - 1e-7)) != np.sign(hermite.value(*c, r + 1e-7)) or r + 1e-7 > 1.0:
            return float(r)
    raise AssertionError(f"no sign change in ({lo}, 1] of {c}")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_crossing_is_the_first_sign_change_on_its_far_side(seed: int) -> None:
    several = 0
    for c in _cubics(seed, 2000):
        u = hermite.crossing(*c, 1.0, 0.0, 0.0)
        assert hermite.value(*c, u) <= _rounding(c)  # the far side (to rounding): θ has reached the plate
        first = _first_root(c, 0.0)
        assert u == pytest.approx(first, abs=1e-9)
        roots = np.roots(c)
        several += int(np.count_nonzero((abs(roots.imag) < 1e-9) & (roots.real > 0) & (roots.real <= 1)) > 1)
    assert several > 100  # the set does hold steps with more than one crossing, where "first" matters


def test_crossing_from_the_peak_to_a_target_either_way() -> None:
    """From u_lo (the step's peak, as after argmax_scaled) down to a target, and with sign −1 (the − pivot)."""
    for c in _cubics(4, 500):
        top = hermite.argmax_scaled(*c, 1.0)
        peak = hermite.value(*c, top)
        target = 0.5 * peak
        if top >= 1.0 or hermite.value(*c, 1.0) > target:
            continue
        u = hermite.crossing(*c, 1.0, target, top)
        assert top < u <= 1.0 and hermite.value(*c, u) <= target + _rounding(c)
        neg = tuple(-x for x in c)
        assert hermite.crossing(*neg, -1.0, target, top) == u  # the mirrored step: the same crossing


def test_argmax_and_stationary_points_against_a_dense_evaluation() -> None:
    u = np.linspace(0.0, 1.0, 100001)
    for c in _cubics(5, 300):
        y = hermite.value(*c, u)
        for sign in (1.0, -1.0):
            best = hermite.argmax_scaled(*c, sign)
            assert sign * hermite.value(*c, best) >= np.max(sign * y) - 1e-12 * np.max(np.abs(y))
        u1, u2 = hermite.stationary_points(*c[:3])
        for r in np.roots([3 * c[0], 2 * c[1], c[2]]):
            if abs(r.imag) < 1e-12:
                assert min(abs(u1 - r.real), abs(u2 - r.real)) < 1e-9 * max(1.0, abs(r.real))
