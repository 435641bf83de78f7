"""The general model at its boundaries (docs/general-model.md, *Ties*): friction exactly b/h, a rest
margin exactly 0 where the block leaves rest, a normal force exactly 0 — one rule in both engines,
and no input makes either loop in place.

Truths: the rocking reference (which the general model reproduces while the pivot neither slips nor
lifts), the statics of a sliding block (with μ ≤ tan α its normal force stays inside the base: it
never tips without vertical input), Eq. 1 (the block rocks iff the record reaches it when μ > b/h),
and Coulomb sliding in closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from analysis import TABLE_V, Body, exceeds_threshold, simulate
from analysis.body import G
from analysis.equations import plate_gravity, rocking_acceleration, sliding_acceleration
from analysis.general_stages import (
    EXIT_FLIGHT,
    EXIT_NONE,
    EXIT_ROCK_MINUS,
    EXIT_ROCK_PLUS,
    EXIT_SLIDE_MINUS,
    EXIT_SLIDE_PLUS,
    TIE,
    friction_tips,
    rest_exit,
    rest_leave,
    rest_margins,
)
from analysis.thresholds import uplift_thresholds

SOME = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def general(body: Body, acc_h, dt: float, solver: str = "fast", **kw):
    return simulate(body, acc_h, dt, model="general", solver=solver, **kw)


# --------------------------------------------------------------------------------------------------
# the rule itself


@pytest.mark.parametrize(("b", "h"), [(0.3, 0.3), (0.1, 0.5), (0.02, 0.1), (0.06, 0.2), (0.13, 0.5)])
def test_friction_equal_to_b_over_h_is_a_tie_whatever_tan_atan_rounds_to(b: float, h: float) -> None:
    """tan(atan(b/h)) is b/h only to rounding (1.0 → 0.9999999999999999): μ = b/h is the tie, and the
    tie slides; beyond the band it rocks."""
    ta = math.tan(Body(b=b, h=h).alpha)
    assert not friction_tips(b / h, ta)
    assert not friction_tips(b / h * (1 - 1e-9), ta)
    assert friction_tips(b / h * (1 + 100 * TIE), ta)


def test_rest_exits_read_one_pair_of_margins() -> None:
    """Friction tips → the uplifts decide, else the slides: never the other pair by rounding. The
    last margin is −g_z: lift-off when > 0; at g_z = 0 exactly the block slides even when friction
    tips (no normal force to pivot on)."""
    assert rest_exit(1.0, 0.0, -1e-300, 0.0, -1.0, True, True) == EXIT_ROCK_PLUS
    assert rest_exit(0.0, 1.0, 0.0, -1.0, -1.0, True, True) == EXIT_ROCK_MINUS
    assert rest_exit(0.0, 0.0, 1.0, 0.0, -1.0, True, True) == EXIT_NONE
    assert rest_exit(1.0, 0.0, 0.0, 0.0, -1.0, False, False) == EXIT_NONE
    assert rest_exit(0.0, 0.0, 1.0, 0.0, -1.0, False, False) == EXIT_SLIDE_PLUS
    assert rest_exit(0.0, 0.0, 0.0, 1.0, -1.0, False, False) == EXIT_SLIDE_MINUS
    assert rest_exit(1.0, 0.0, 1.0, 0.0, 0.0, True, True) == EXIT_SLIDE_PLUS
    assert rest_exit(1.0, 0.0, 1.0, 0.0, 1e-300, True, True) == EXIT_FLIGHT


@pytest.mark.parametrize("tips", [True, False])
def test_the_block_leaves_rest_where_the_stage_it_enters_accelerates(tips: bool) -> None:
    """A ramp whose computed root has the margin 0 or below by rounding: rest_leave returns a time at
    which the entered stage's own acceleration (θ'' on the pivot, the slide's v' times slip) is > 0,
    within a few ulps of the root."""
    body = Body(b=0.06, h=0.2)
    alpha, ca, sa = body.alpha, math.cos(body.alpha), math.sin(body.alpha)
    k = body.r / (body.i_g**2 + body.r**2)
    mu = 5.0 if tips else math.tan(alpha)
    hits = 0
    for i in range(200):  # the ramp −0.05 g/s sampled at 0.01 s, and shifted copies of it
        t_a, dt = 5.99 + i * 1e-4, 0.01
        a0, slope = -0.05 * G * t_a, -0.05 * G
        t_x, kind = rest_leave(t_a, t_a + dt, t_a, a0, slope, 0.0, 0.0, a0 + slope * dt, 0.0, 1.0, 0.0, ca, sa, ca,
                               sa, mu, tips, tips)
        if kind == EXIT_NONE:
            continue
        hits += 1
        gx, gz = plate_gravity(a0 + slope * (t_x - t_a), 0.0, 1.0, 0.0)
        if tips:
            assert kind == EXIT_ROCK_PLUS and rocking_acceleration(0.0, 1.0, gx, gz, alpha, k) > 0.0
        else:
            assert kind == EXIT_SLIDE_PLUS and sliding_acceleration(1.0, gx, gz, mu) > 0.0
        root = t_a + dt * rest_margins(a0, 0.0, 1.0, 0.0, ca, sa, ca, sa, mu)[0 if tips else 2] / (
            rest_margins(a0, 0.0, 1.0, 0.0, ca, sa, ca, sa, mu)[0 if tips else 2]
            - rest_margins(a0 + slope * dt, 0.0, 1.0, 0.0, ca, sa, ca, sa, mu)[0 if tips else 2])
        assert abs(t_x - max(root, t_a)) < 1e-13  # from the interval's start if it is already past
    assert hits > 0


# --------------------------------------------------------------------------------------------------
# the reproductions


def test_uplift_margin_exactly_zero_where_rocking_starts() -> None:
    """Issue 26: the reference made 13,723 impacts at t = 5.999999999999998 with max θ 0. Friction 5
    (no slip): the general model is the rocking model, whose reference gives the truth."""
    body = Body(b=0.06, h=0.2)
    acc = -0.05 * np.arange(0, 6.3, 0.01)
    truth = simulate(body, acc, 0.01, model="rocking", solver="reference", t_after=0.0)
    assert truth.theta_max > 0.02
    for solver in ("reference", "fast"):
        res = general(body, acc, 0.01, solver, friction=5.0, t_after=0.0)
        assert res.impacts == truth.impacts == 0
        assert res.status == truth.status == "undecided"  # still rocking when the record ends (t_after 0)
        assert res.theta_max == pytest.approx(truth.theta_max, rel=1e-6 if solver == "fast" else 1e-9)
        assert res.slide_time == 0.0


def test_rocking_on_a_rounded_1_ms_grid_goes_on_to_the_end_of_the_record() -> None:
    """A 1 kHz record whose interval reads 0.0010000000000000002 s (the rig's sample clock, rounded): Table V
    body 1 rocks 20 s on a 0.25 g, 3 Hz sine with e = 0.9. The rocking kernel compiled with fused multiply-adds
    held t at 16.002000000000002 for ever (an exact product where the step grid needs the rounded one: a step
    of zero length; a whole ``rig analyze`` of a tap hung on it). Both fast engines must rock on to the end of
    the record (t_after 0: ``undecided``, still rocking) with the reference solver's largest angle and impacts."""
    dt = 0.0010000000000000002
    acc = 0.25 * np.sin(2 * np.pi * 3.0 * np.arange(0, 20.0, 0.001))
    t_end = acc.size * dt  # the engines add one trailing zero sample
    truth = simulate(TABLE_V[0], acc, dt, model="rocking", solver="reference", restitution=0.9, t_after=0.0)
    assert truth.status == "undecided" and truth.t_end == pytest.approx(t_end) and truth.impacts > 100
    for model in ("rocking", "general"):
        res = simulate(TABLE_V[0], acc, dt, model=model, solver="fast", restitution=0.9, t_after=0.0)
        assert res.status == "undecided" and res.t_end == pytest.approx(t_end, abs=1e-9), (model, res)
        assert res.impacts == truth.impacts, (model, res.impacts, truth.impacts)
        assert res.theta_max == pytest.approx(truth.theta_max, rel=1e-3), (model, res.theta_max, truth.theta_max)


def test_a_weightless_block_slides_instead_of_looping_in_place() -> None:
    """Level plate, vertical input exactly −1 g (gz = 0: no normal force, no friction) and a
    horizontal ramp: the block slides frictionless, v' = −a_x, then friction stops it once g returns.
    The fast engine used to loop at t = 0 (flight of zero length, flat landing, rest, again: 336,308
    impacts). Closed form: a_x = −c t over T, so v(T) = c T²/2, u(T) = c T³/6; one sample ramps both
    inputs to zero (a_x from −c T, gz from 0 to g), then v' = −μ g."""
    body, dt, n, c, mu = Body(b=0.02, h=0.1), 0.02, 100, 0.3, 0.5
    t = np.arange(n) * dt
    acc_h, acc_v = -c * t, -np.ones(n)
    T = t[-1]
    v_T, u_T = c * G * T**2 / 2, c * G * T**3 / 6
    # the last sample interval: a_x from −cT to 0 and gz from 0 to g, linearly over dt:
    # v' = c g T (1 − τ/dt) − μ g τ/dt
    v_r = v_T + c * G * T * dt / 2 - mu * G * dt / 2
    u_r = u_T + v_T * dt + c * G * T * dt**2 / 3 - mu * G * dt**2 / 6
    u_stop = u_r + v_r**2 / (2 * mu * G)
    for solver in ("fast", "reference"):
        res = general(body, acc_h, dt, solver, acc_v=acc_v, friction=mu, t_after=3.0)
        assert (res.status, res.direction, res.theta_max, res.impacts) == ("rest", 0, 0.0, 0)
        assert res.slide_residual == pytest.approx(u_stop, rel=1e-9)
        assert res.t_end == pytest.approx(T + dt + v_r / (mu * G), abs=1e-9)


@pytest.mark.slow
def test_friction_exactly_b_over_h_on_a_fema_record() -> None:
    """Issue 26: `rig simulate fema:CAPEMEND/CPM_350 --body 0.3x0.3 --angle 3 --model general --solver
    reference --sign -1` ended `undecided` at 2.952 s (max θ 0) and the fast engine counted a phantom
    impact. μ = 1 = b/h is the tie: the block slides, never rotates, and both engines agree."""
    from rig.records import load_record

    rec = load_record("fema:CAPEMEND/CPM_350")
    out = [general(Body(b=0.3, h=0.3), -rec.acc_h, rec.dt, solver, beta=math.radians(3.0))
           for solver in ("fast", "reference")]
    for res in out:
        assert (res.status, res.theta_max, res.impacts) == ("rest", 0.0, 0)
        assert res.slide_time > 0.0
    assert out[0].t_end == pytest.approx(out[1].t_end, abs=1e-6)
    assert out[0].slide_residual == pytest.approx(out[1].slide_residual, rel=1e-6)


# --------------------------------------------------------------------------------------------------
# property: μ = b/h ± ε


@st.composite
def tie_scenes(draw) -> tuple[Body, np.ndarray, float, float]:
    """(body, acc_h [g], dt, β): b/h in [0.1, 1], β in [0, 0.8 α), a record of sines up to 10 g."""
    aspect = draw(st.floats(0.1, 1.0))
    h = draw(st.floats(0.1, 1.5))
    body = Body(b=aspect * h, h=h)
    beta = draw(st.floats(0.0, 0.8, exclude_max=True)) * body.alpha
    n = draw(st.integers(100, 400))
    dt = draw(st.sampled_from([0.005, 0.01, 0.02]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    t = np.arange(n) * dt
    acc = sum(rng.normal() * np.sin(2 * np.pi * rng.uniform(0.3, 8.0) * t + rng.uniform(0, 2 * np.pi))
              for _ in range(3)) * np.sin(np.pi * t / t[-1])
    acc = np.asarray(acc) * draw(st.floats(0.05, 10.0)) / max(np.max(np.abs(acc)), 1e-300)
    # horizontal input alone never lifts the block off the incline here (g_z = a sin β + g cos β > 0),
    # and the record does not peak within 1e-9 of Eq. 1 (a tie of the record, not of friction)
    assume(np.all(acc * math.sin(beta) + math.cos(beta) > 0.0))
    a_plus, a_minus = uplift_thresholds(body, beta, 0.0, 1.0)
    assume(abs(np.max(-acc) / a_plus - 1.0) > 1e-9 and abs(np.max(acc) / a_minus - 1.0) > 1e-9)
    return body, acc, dt, beta


@SOME
@given(scene=tie_scenes(), eps=st.floats(1e-9, 1e-3))
def test_at_and_below_b_over_h_the_block_slides_and_never_rotates(scene, eps: float) -> None:
    """With μ ≤ b/h (the tie included) and no vertical input, a flat sliding block's normal force stays
    inside its base: no rotation, no impact (the fast engine counted 61 phantom impacts at
    μ = b/h). At the tie the slide is the limit of μ → b/h from below: the same outcome, and a slide
    that differs by O(ε): relatively, or — near the onset of sliding, where a slide of nanometres may grow
    many-fold — by at most what the friction force's change ε·μ·N can move a block in the time either slid,
    ½ ε μ g_N,max T² (N ≤ m g (cos β + max|a| sin β))."""
    body, acc, dt, beta = scene
    note(f"Body(b={body.b!r}, h={body.h!r}), beta={beta!r}, dt={dt}, n={acc.size}, eps={eps!r}")
    tie = general(body, acc, dt, beta=beta, friction=body.b / body.h, t_after=5.0)
    below = general(body, acc, dt, beta=beta, friction=body.b / body.h * (1 - eps), t_after=5.0)
    for res in (tie, below):
        assert (res.theta_max, res.impacts, res.direction) == (0.0, 0, 0)
        assert res.status in ("rest", "undecided")
    assert tie.status == below.status
    mu = body.b / body.h
    g_normal = G * (math.cos(beta) + np.max(np.abs(acc)) * math.sin(beta))
    sliding = max(tie.slide_time, below.slide_time)
    assert tie.slide_peak == pytest.approx(below.slide_peak, rel=1e3 * eps,
                                           abs=max(1e-12, 0.5 * eps * mu * g_normal * sliding**2))


@SOME
@given(scene=tie_scenes(), eps=st.floats(1e-6, 1e-3))
def test_above_b_over_h_the_block_rocks_iff_eq1_is_reached(scene, eps: float) -> None:
    """With μ > b/h beyond the tie, a resting block leaves rest by uplift (Eq. 1), never by a slide:
    it rotates iff the record reaches Eq. 1, and never counts an impact without rotating."""
    body, acc, dt, beta = scene
    note(f"Body(b={body.b!r}, h={body.h!r}), beta={beta!r}, dt={dt}, n={acc.size}, eps={eps!r}")
    res = general(body, acc, dt, beta=beta, friction=body.b / body.h * (1 + eps), t_after=5.0)
    assert (res.theta_max > 0.0) == exceeds_threshold(body, beta, acc * G)
    if res.theta_max == 0.0:
        assert (res.impacts, res.slide_time, res.status) == (0, 0.0, "rest")


def test_at_the_tie_both_engines_agree_on_random_records() -> None:
    """The same rule in both engines: a few tie scenes through the reference too."""
    rng = np.random.default_rng(26)
    for _ in range(3):
        body = Body(b=rng.uniform(0.1, 0.3), h=rng.uniform(0.3, 0.6))
        t = np.arange(300) * 0.01
        acc = rng.uniform(0.5, 3.0) * np.sin(2 * np.pi * rng.uniform(0.5, 3) * t) * np.sin(np.pi * t / t[-1])
        kw = dict(beta=rng.uniform(0, 0.5) * body.alpha, friction=body.b / body.h, t_after=3.0)
        fast, ref = general(body, acc, 0.01, "fast", **kw), general(body, acc, 0.01, "reference", **kw)
        assert (fast.status, fast.theta_max, fast.impacts) == (ref.status, ref.theta_max, ref.impacts)
        assert ref.theta_max == 0.0 and ref.slide_time > 0.0
        assert fast.slide_residual == pytest.approx(ref.slide_residual, rel=1e-7)
        assert fast.slide_time == pytest.approx(ref.slide_time, rel=1e-7)
