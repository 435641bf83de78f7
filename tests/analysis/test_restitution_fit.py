"""`analysis.restitution`: a body's restitution read from its sampled angle, against the reference solver run with
a known restitution (the ratio it applies at every impact is the truth), free and under shaking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from analysis import AnalysisInputError, Body, simulate
from analysis.restitution import Impact, fit_restitution, impact_ratios

BODY = Body(b=0.1, h=0.5)
HOUSNER = 1.0 - 1.5 * math.sin(BODY.alpha) ** 2
TILT_SAMPLE = 0.005
"""The tilt sensors' sample period [s] (200 Hz)."""


def sampled_angle(result, offset: float = 0.0017) -> tuple[np.ndarray, np.ndarray]:
    """The reference solution's angle at 200 Hz (sample times not aligned with anything): its steps joined by
    cubic Hermite curves through their angles and rates, the impacts (repeated times) as jumps of the rate."""
    trace = result.trace
    t, theta, omega = (np.asarray(v) for v in (trace.t, trace.theta, trace.omega))
    samples = np.arange(offset, t[-1], TILT_SAMPLE)
    angle = np.full(samples.shape, np.nan)
    for piece in np.split(np.arange(t.size), np.flatnonzero(np.diff(t) <= 0) + 1):
        if piece.size < 2:
            continue
        inside = (samples >= t[piece[0]]) & (samples <= t[piece[-1]])
        angle[inside] = CubicHermiteSpline(t[piece], theta[piece], omega[piece])(samples[inside])
    known = np.isfinite(angle)
    return samples[known], angle[known]


@pytest.mark.parametrize("restitution", [HOUSNER, 0.9, 0.7])
@pytest.mark.parametrize("beta_deg", [0.0, 4.0])
def test_free_rocking_gives_back_the_solvers_restitution(restitution: float, beta_deg: float) -> None:
    result = simulate(BODY, np.zeros(10), 0.01, beta=math.radians(beta_deg), solver="reference",
                      restitution=restitution, theta0=0.5 * BODY.alpha, history=True, t_after=5.0)
    fit = fit_restitution(impact_ratios(*sampled_angle(result)))
    assert fit.impacts >= 4
    assert fit.value == pytest.approx(restitution, rel=0.015)
    assert fit.low <= fit.value <= fit.high
    assert fit.high - fit.low < 0.02


def test_impacts_during_shaking_give_the_restitution_too() -> None:
    t = np.arange(0.0, 4.0, 0.01)
    pulse = 0.3 * np.sin(2 * np.pi * 2 * t) * np.exp(-(((t - 1.5) / 0.7) ** 2))  # [g], rocks and stops
    result = simulate(BODY, pulse, 0.01, solver="reference", restitution=0.7, history=True, t_after=5.0)
    assert result.status == "rest" and len(result.trace.impacts) > 10
    impacts = impact_ratios(*sampled_angle(result))
    assert len(impacts) >= 5
    assert fit_restitution(impacts).value == pytest.approx(0.7, rel=0.02)
    # each impact found is one the solver made, at its time
    made = np.array([t_impact for t_impact, _, _ in result.trace.impacts])
    assert all(np.min(np.abs(made - impact.t)) < 1e-3 for impact in impacts)


def test_a_resting_body_has_no_impacts() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 10.0, TILT_SAMPLE)
    assert impact_ratios(t, 2e-4 * rng.standard_normal(t.size)) == []


def test_a_gap_in_the_samples_skips_the_impacts_it_hides() -> None:
    result = simulate(BODY, np.zeros(10), 0.01, solver="reference", restitution=0.9, theta0=0.5 * BODY.alpha,
                      history=True, t_after=5.0)
    t, angle = sampled_angle(result)
    first = impact_ratios(t, angle)[0].t
    keep = np.abs(t - first) > 0.02  # a lost batch around the first impact
    remaining = impact_ratios(t[keep], angle[keep])
    assert first not in [impact.t for impact in remaining]
    assert len(remaining) == len(impact_ratios(t, angle)) - 1


def test_the_interval_is_that_of_the_median() -> None:
    ratios = np.linspace(0.80, 0.99, 20)
    fit = fit_restitution([Impact(float(k), -1.0, -r) for k, r in enumerate(ratios)])
    assert fit.impacts == 20 and fit.value == pytest.approx(np.median(ratios))
    # n = 20: the 6th and 15th order statistics (P(B(20, ½) ≤ 5) = 2.1 % on each side)
    assert (fit.low, fit.high) == (pytest.approx(ratios[5]), pytest.approx(ratios[14]))
    empty = fit_restitution([])
    assert empty.impacts == 0 and math.isnan(empty.value)


def test_bad_input_is_named() -> None:
    with pytest.raises(AnalysisInputError, match="must match"):
        impact_ratios([0.0, 0.1], [0.0])
    with pytest.raises(AnalysisInputError, match="increase"):
        impact_ratios([0.0, 0.0, 0.1], [0.0, 0.1, 0.2])
    with pytest.raises(AnalysisInputError, match="finite"):
        impact_ratios([0.0, 0.1], [0.0, math.nan])
    with pytest.raises(AnalysisInputError, match="gap"):
        impact_ratios([0.0, 0.1], [0.0, 0.1], gap=0.05, window=0.04)


def test_a_body_put_back_upright_is_not_an_impact() -> None:
    """Between runs a fallen body (θ = −π/2) is stood up again: its angle jumps to 0, where it rests with
    rounding-level values that change sign within the window of the jump (as the emulator's sessions show)."""
    t = np.arange(0.0, 1.0, TILT_SAMPLE) + 0.0021
    angle = np.where(t < 0.5, -0.5 * math.pi, 1e-30 * (t - 0.52))
    assert impact_ratios(t, angle) == []
