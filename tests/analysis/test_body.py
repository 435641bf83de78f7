"""Body geometry (Table I) and Eq. 1's thresholds against the paper and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import TABLE_I, AnalysisInputError, Body, simulate, uplift_thresholds
from analysis.body import G

# the paper's Table I, rows b/h, r (m) and α (rad) as printed
TABLE_I_ASPECT = [0.20, 0.25, 0.30, 0.20, 0.26, 0.30, 0.36, 0.20, 0.25, 0.30, 0.20, 0.25]
TABLE_I_R = [0.10, 0.10, 0.10, 0.25, 0.26, 0.26, 0.27, 0.51, 0.52, 0.52, 0.76, 0.77]
TABLE_I_ALPHA = [0.20, 0.24, 0.29, 0.20, 0.25, 0.29, 0.35, 0.20, 0.24, 0.29, 0.20, 0.25]


@pytest.mark.parametrize("j", range(12))
def test_table_i_rows_come_out_to_the_printed_decimals(j: int) -> None:
    body = TABLE_I[j]
    assert round(body.aspect, 2) == TABLE_I_ASPECT[j]
    assert round(body.r, 2) == TABLE_I_R[j]
    assert round(body.alpha, 2) == TABLE_I_ALPHA[j]


def test_uniform_block_inertia_and_frequency() -> None:
    body = Body(b=0.3, h=1.2)
    assert body.i_g**2 == pytest.approx(body.r**2 / 3)  # uniform rectangle: I_G = m (b² + h²)/12
    assert body.p == pytest.approx(math.sqrt(3 * G / (4 * body.r)))
    v_body = Body.from_p_alpha(2.0, 0.2)
    assert v_body.p == pytest.approx(2.0) and v_body.alpha == pytest.approx(0.2)


@pytest.mark.parametrize("beta_deg", [0.0, 3.0, 7.0])
@pytest.mark.parametrize("a_v", [0.0, -0.3, 0.4])
def test_eq1_thresholds_in_the_papers_form(beta_deg: float, a_v: float) -> None:
    body = Body(b=0.10, h=0.50)
    beta = math.radians(beta_deg)
    a_plus, a_minus = uplift_thresholds(body, beta, a_v * G)
    bh = body.b / body.h
    assert a_plus == pytest.approx((a_v * G + G) * (bh - math.tan(beta)) / (1 + bh * math.tan(beta)), rel=1e-12)
    assert a_minus == pytest.approx((a_v * G + G) * (bh + math.tan(beta)) / (1 - bh * math.tan(beta)), rel=1e-12)
    if beta_deg > 0:
        assert a_plus < a_minus  # the tilt makes rocking towards the low side easier (Fig. 2)


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize(("side", "factor", "moves"), [(1, 0.999, False), (1, 1.001, True),
                                                       (-1, 0.999, False), (-1, 1.001, True)])
def test_the_block_starts_rocking_exactly_at_eq1(model: str, side: int, factor: float, moves: bool) -> None:
    """A constant plate acceleration just below / above Eq. 1 (uphill for +x rocking, downhill for
    −x) with a vertical component leaves the block at rest / starts it rocking on that side."""
    body = Body(b=0.10, h=0.50)
    beta, a_v = math.radians(4.0), -0.2
    a_plus, a_minus = uplift_thresholds(body, beta, a_v * G)
    a = (-a_plus if side > 0 else a_minus) * factor / G
    n = 200
    for solver in ("fast", "reference"):
        res = simulate(body, np.full(n, a), 0.01, beta=beta, acc_v=np.full(n, a_v), model=model, solver=solver,
                       friction=5.0, t_after=5.0)
        assert (res.theta_max > 0) == moves, (solver, res)
        if moves:
            assert res.direction in (0, side)


def test_bad_bodies_are_refused_with_the_field_named() -> None:
    with pytest.raises(AnalysisInputError, match="h must be"):
        Body(b=0.1, h=0.0)
    with pytest.raises(AnalysisInputError, match="BxH"):
        Body.parse("0.1*0.5")
