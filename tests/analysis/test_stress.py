"""Numerical stability under stress (VALIDATION.md, robustness row): bodies with b/h 0.05–1 and
heights 0.05–5 m, β up to just below α, restitution 0–0.95, sample steps 0.001–0.02 s, and for
the general model vertical acceleration beyond g. No NaN, no hang (the step count stays within
what the record's length allows), energy never grows in free motion, agreement with the reference.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pytest

from analysis import Body, simulate
from analysis.body import G
from analysis.study import StudyResult, study

ASPECTS = (0.05, 0.2, 0.5, 1.0)
HEIGHTS = (0.05, 0.5, 5.0)
RESTITUTIONS = (0.0, 0.5, 0.95)
DTS = (0.001, 0.02)
T_AFTER = 20.0


@dataclass
class Rec:
    name: str
    dt: float
    acc_h: np.ndarray
    acc_v: np.ndarray | None = None


def record(dt: float, seed: int, duration: float = 6.0, pga: float = 0.8, vertical: float | None = None) -> Rec:
    """Band-limited seeded noise (sum of random sines 0.5–8 Hz) with a taper, peak ``pga`` [g]."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, dt)
    f = rng.uniform(0.5, 8.0, 12)
    ph = rng.uniform(0, 2 * np.pi, 12)
    a = np.sin(2 * np.pi * f[:, None] * t + ph[:, None]).sum(axis=0) * np.sin(np.pi * t / duration) ** 2
    acc_v = None
    if vertical is not None:
        v = np.sin(2 * np.pi * rng.uniform(1, 6) * t) * np.sin(np.pi * t / duration) ** 2
        acc_v = vertical * v / np.abs(v).max()
    return Rec(f"noise-{seed}-{dt}", dt, pga * a / np.abs(a).max(), acc_v)


def bodies() -> list[Body]:
    return [Body(b=asp * h, h=h) for asp, h in itertools.product(ASPECTS, HEIGHTS)]


def step_bound(res: StudyResult, recs: list[Rec]) -> np.ndarray:
    """The most RK4 steps a scene can take: its grid steps plus two per event (no vanishing step)."""
    n_sub = np.array([[math.ceil(b.p * r.dt / 0.05 - 1e-9) for b in res.bodies] for r in recs])
    samples = np.array([r.acc_h.size + T_AFTER / r.dt for r in recs])
    sub = n_sub[res.record, res.body]
    return sub * (samples[res.record] + 2) + 2 * res.impacts + 10


@pytest.mark.slow
@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize("restitution", RESTITUTIONS)
def test_no_nan_no_hang_over_the_robustness_grid(model: str, restitution: float) -> None:
    if model == "general":
        pytest.importorskip("analysis.fast_general")
    recs = [record(dt, seed) for dt in DTS for seed in (1, 2)]
    if model == "general":
        recs += [record(dt, 3, vertical=1.4) for dt in DTS]  # the plate drops faster than g: jumps
    bs = bodies()
    angles = [0.0, 0.5, 0.95]  # fractions of each body's α: run per body
    for frac in angles:
        for body in bs:
            res = study([body], recs, [frac * body.alpha], model=model, restitution=restitution, t_after=T_AFTER)
            assert np.all(np.isfinite(res.theta_max))
            over = res.direction != 0
            assert np.all(np.isfinite(res.t_overturn[over])) and np.all(np.isnan(res.t_overturn[~over]))
            assert np.all((res.status == 1) == over)
            assert np.all(res.steps <= step_bound(res, recs)), "a scene took more steps than its record allows"


def cm_energy(body: Body, beta: float, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Mechanical energy per unit mass in free motion on the inclined plate: ½ I_O/m ω² + g z_cm,
    z_cm measured from the downhill corner (continuous across corner changes)."""
    r, a = body.r, body.alpha
    io = body.r**2 + body.i_g**2
    z = np.where(theta >= 0, r * np.cos(a - beta - theta), body.b * math.sin(beta) + r * np.cos(a + beta + theta))
    return 0.5 * io * omega**2 + G * z


@pytest.mark.slow
@pytest.mark.parametrize("restitution", [0.3, 0.7, 0.95])
@pytest.mark.parametrize(("aspect", "height", "beta_frac"), [(0.2, 1.0, 0.0), (0.3, 0.2, 0.6), (1.0, 5.0, 0.9)])
def test_energy_never_grows_in_free_motion(restitution: float, aspect: float, height: float, beta_frac: float) -> None:
    body = Body(b=aspect * height, h=height)
    beta = beta_frac * body.alpha
    theta0 = 0.6 * (body.alpha - beta)  # released on the downhill corner, short of tipping over
    res = simulate(body, np.zeros(2), 0.01, beta=beta, theta0=theta0, restitution=restitution,
                   solver="reference", history=True, t_after=30.0)
    assert res.status == "rest"
    energy = cm_energy(body, beta, np.array(res.trace.theta), np.array(res.trace.omega))
    scale = G * body.r
    assert np.all(np.diff(energy) <= 1e-8 * scale), f"energy grew by {np.diff(energy).max() / scale:.3g} (relative)"
    fast = simulate(body, np.zeros(2), 0.01, beta=beta, theta0=theta0, restitution=restitution, t_after=30.0)
    assert fast.status == "rest" and fast.direction == 0
    assert fast.t_end == pytest.approx(res.t_end, abs=1e-3)


@pytest.mark.slow
def test_fast_agrees_with_reference_under_stress() -> None:
    """Direction agreement over extreme bodies and steps; a differing scene must be chaotic (a 1e-6
    perturbation of the record flips the reference too)."""
    rng = np.random.default_rng(11)
    unexplained = []
    for n in range(40):
        aspect, height = rng.choice(ASPECTS), rng.choice(HEIGHTS)
        body = Body(b=aspect * height, h=height)
        beta = rng.uniform(0, 0.95) * body.alpha
        e = float(rng.choice(RESTITUTIONS))
        rec = record(float(rng.choice([0.002, 0.005, 0.02])), 100 + n, duration=4.0, pga=float(rng.uniform(0.3, 1.5)))
        fast = simulate(body, rec.acc_h, rec.dt, beta=beta, restitution=e, t_after=T_AFTER)
        ref = simulate(body, rec.acc_h, rec.dt, beta=beta, restitution=e, t_after=T_AFTER, solver="reference")
        if fast.direction != ref.direction:
            flips = [simulate(body, rec.acc_h * (1 + s), rec.dt, beta=beta, restitution=e, t_after=T_AFTER,
                              solver="reference").direction != ref.direction for s in (1e-6, -1e-6)]
            if not any(flips):
                unexplained.append((body, beta, e, rec.name, fast.direction, ref.direction))
    assert not unexplained
