"""Blocks whose centre of mass is off the centroid (Table V's b_cg, h_cg): each corner's slenderness, radius,
inertia and impact, in both models and both solvers.

Truths used here, none of them this code's own output: the closed forms of Eq. 1 per side (tan α± = d±/h_cg),
angular momentum about the landing corner computed with plane vectors, an independent Newton–Euler solve with
the centre of mass placed by rotation matrices, energy conservation between impacts and the exact ω at impact
of free rocking, Housner's linearised free rocking solved in closed form on each side, the centred block
(b_cg = b/2, h_cg = h/2 must give the numbers a block without a centre of mass given gives, bit for bit),
mirror symmetry (the block turned round, b_cg → b − b_cg, under the negated input and β → −β), and the
reference solver for the fast engine.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import AnalysisInputError, Body, simulate, uplift_thresholds
from analysis.body import TABLE_V, G
from analysis.equations import pivot_reactions, plate_gravity, rocking_acceleration, rocking_sliding_acceleration
from analysis.fast_general import ST_FLIGHT, ST_ROCK, ST_ROCKSLIDE, landing_omega
from analysis.simulate import check_angle, resolve_restitutions
from tests.helpers.newton_euler import centre_from_pivot, newton_euler, rot

T5_1 = Body(b=0.099, h=0.493, depth=0.2012, mass=5.22, b_cg=0.0515, h_cg=0.243, name="T5-1")
"""Table V's body 1 as printed (b_cg read from the −x corner)."""
LOPSIDED = Body(b=0.2, h=0.8, b_cg=0.13, h_cg=0.35)
"""Far more off-centre than any Table V block, so that every per-side difference shows."""
DT = 0.01


def _record(rng: np.random.Generator, n: int, amp: float) -> np.ndarray:
    t = np.arange(n) * DT
    env = np.sin(np.pi * t / t[-1]) ** 2
    a = np.zeros(n)
    for _ in range(3):
        a += rng.uniform(-1, 1) * np.sin(2 * np.pi * rng.uniform(0.5, 4) * t + rng.uniform(0, 6.3))
    return amp * env * a / np.max(np.abs(a))


# --------------------------------------------------------------------------------------------------
# the body


def test_table_v_body_1_slenderness_on_each_side() -> None:
    """b = 99 mm, b_cg = 51.5 mm, h_cg = 243 mm: 47.5 mm to the +x corner, 51.5 mm to the −x corner."""
    assert T5_1.d_plus == pytest.approx(0.0475, abs=1e-15) and T5_1.d_minus == 0.0515
    assert math.degrees(T5_1.alpha_plus) == pytest.approx(math.degrees(math.atan(47.5 / 243)), rel=1e-14)
    assert math.degrees(T5_1.alpha_minus) == pytest.approx(math.degrees(math.atan(51.5 / 243)), rel=1e-14)
    assert round(math.degrees(T5_1.alpha_plus), 2) == 11.06 and round(math.degrees(T5_1.alpha_minus), 2) == 11.97
    assert T5_1.r_plus == pytest.approx(math.hypot(0.0475, 0.243), rel=1e-15)
    assert T5_1.r_minus == pytest.approx(math.hypot(0.0515, 0.243), rel=1e-15)
    # moment of inertia about each corner: the uniform block's about the centre of mass (the stated
    # assumption), shifted by the parallel-axis theorem
    i_cg = T5_1.mass * (0.099**2 + 0.493**2) / 12
    assert T5_1.inertia_plus() == pytest.approx(i_cg + T5_1.mass * (0.0475**2 + 0.243**2), rel=1e-14)
    assert T5_1.inertia_minus() == pytest.approx(i_cg + T5_1.mass * (0.0515**2 + 0.243**2), rel=1e-14)
    assert T5_1.p_plus == pytest.approx(math.sqrt(G * T5_1.mass * T5_1.r_plus / T5_1.inertia_plus()), rel=1e-14)
    assert T5_1.k_minus == pytest.approx(T5_1.p_minus**2 / G, rel=1e-14)
    assert not T5_1.symmetric and not T5_1.centred


def test_table_v_carries_the_papers_centres_of_gravity() -> None:
    printed = [(99, 493, 51.5, 243), (130, 500, 65, 254), (152, 500, 76.5, 251.5), (39, 200, 19.5, 100),
               (49, 200, 25, 100), (200, 998, 100, 495), (248, 995, 124, 499)]
    for body, (b, h, b_cg, h_cg) in zip(TABLE_V, printed, strict=True):
        assert (body.b, body.h, body.b_cg, body.h_cg) == pytest.approx((b / 1e3, h / 1e3, b_cg / 1e3, h_cg / 1e3))
        assert body.alpha_plus == pytest.approx(math.atan((b - b_cg) / h_cg), rel=1e-12)
        assert body.alpha_minus == pytest.approx(math.atan(b_cg / h_cg), rel=1e-12)


def test_mirrored_body_swaps_the_sides() -> None:
    m = LOPSIDED.mirrored()
    assert m.b_cg == pytest.approx(0.07, abs=1e-16)
    assert (m.alpha_plus, m.alpha_minus) == pytest.approx((LOPSIDED.alpha_minus, LOPSIDED.alpha_plus), rel=1e-14)
    assert (m.r_plus, m.r_minus) == pytest.approx((LOPSIDED.r_minus, LOPSIDED.r_plus), rel=1e-14)
    e_p, e_m = LOPSIDED.housner_restitutions()
    assert m.housner_restitutions() == pytest.approx((e_m, e_p), rel=1e-14)
    assert Body(0.1, 0.5).mirrored() == Body(0.1, 0.5)


@pytest.mark.parametrize(("b", "h"), [(0.1, 0.5), (0.099, 0.493), (0.3, 0.3), (0.0025, 0.05), (1.0, 5.0)])
def test_centre_of_mass_at_the_centroid_is_the_uniform_block_bit_for_bit(b: float, h: float) -> None:
    plain, given = Body(b, h), Body(b, h, b_cg=b / 2, h_cg=h / 2)
    assert given.centred and given.symmetric
    for body in (plain, given):
        assert (body.alpha_plus, body.alpha_minus) == (plain.alpha, plain.alpha)
        assert (body.r_plus, body.r_minus) == (plain.r, plain.r)
        assert (body.p_plus, body.p_minus) == (plain.p, plain.p)
        assert body.housner_restitutions() == (plain.housner_restitution(), plain.housner_restitution())
        assert body.k_plus == plain.r / (plain.i_g**2 + plain.r**2)


@pytest.mark.parametrize(("kw", "words"), [
    (dict(b_cg=0.0), ["b_cg", "0 < b_cg < b"]),
    (dict(b_cg=0.1), ["b_cg", "-x corner"]),
    (dict(b_cg=-0.01), ["b_cg"]),
    (dict(b_cg=math.nan), ["b_cg"]),
    (dict(h_cg=0.5), ["h_cg", "0 < h_cg < h"]),
    (dict(h_cg=0.0), ["h_cg", "above the base"]),
    (dict(h_cg=math.inf), ["h_cg"]),
])
def test_a_centre_of_mass_outside_the_block_is_refused(kw: dict, words: list[str]) -> None:
    with pytest.raises(AnalysisInputError) as err:
        Body(b=0.1, h=0.5, **kw)
    for word in words:
        assert word in str(err.value)


def test_housners_single_value_is_refused_where_it_depends_on_the_direction() -> None:
    with pytest.raises(AnalysisInputError, match="housner_restitutions"):
        LOPSIDED.housner_restitution()
    # a centre of mass off the middle in height only: the sides are alike, one value both ways
    tall = Body(0.2, 0.8, h_cg=0.3)
    e_p, e_m = tall.housner_restitutions()
    assert tall.housner_restitution() == e_p == e_m
    assert e_p != pytest.approx(1 - 1.5 * math.sin(tall.alpha_plus) ** 2)  # not the uniform-block formula


def test_the_command_line_body_takes_the_centre_of_gravity() -> None:
    assert Body.parse("0.099x0.493;cg=0.0515,0.243") == Body(0.099, 0.493, b_cg=0.0515, h_cg=0.243)
    assert Body.parse("0.1x0.5") == Body(0.1, 0.5)
    for bad in ("0.1x0.5;cg=0.05", "0.1x0.5;mass=3", "0.1x0.5;cg=a,b"):
        with pytest.raises(AnalysisInputError, match="BxH\\[;cg=BCG,HCG\\]"):
            Body.parse(bad)
    with pytest.raises(AnalysisInputError, match="0 < b_cg < b"):
        Body.parse("0.1x0.5;cg=0.1,0.25")


# --------------------------------------------------------------------------------------------------
# the impact: angular momentum about the landing corner


def _impact_ratio(body: Body, old: float) -> float:
    """ω⁺/ω⁻ of a plastic, sticking impact ending rocking on corner ``old`` (±1), from plane vectors: the
    corners at x = b (+) and 0 (−), the centre of mass at (b_cg, h_cg); angular momentum about the new corner
    is I_G ω + m (r × v_G) before and I_new ω⁺ after."""
    b_cg, h_cg = body.cg
    ig2 = body.i_g**2
    corner = {1.0: np.array([body.b, 0.0]), -1.0: np.array([0.0, 0.0])}
    g = np.array([b_cg, h_cg])
    r_old, r_new = g - corner[old], g - corner[-old]
    omega = 1.0  # any rate (counter-clockwise about the plate's normal to the plane)
    v_g = omega * np.array([-r_old[1], r_old[0]])
    h_before = ig2 * omega + (r_new[0] * v_g[1] - r_new[1] * v_g[0])
    return h_before / (ig2 + float(r_new @ r_new)) / omega


@pytest.mark.parametrize("body", [T5_1, LOPSIDED, LOPSIDED.mirrored(), Body(0.3, 0.4, b_cg=0.05, h_cg=0.3),
                                  Body(0.1, 0.5, b_cg=0.05, h_cg=0.2)])
def test_housners_restitution_per_direction_from_angular_momentum(body: Body) -> None:
    e_p, e_m = body.housner_restitutions()
    assert e_p == pytest.approx(_impact_ratio(body, 1.0), rel=1e-13)
    assert e_m == pytest.approx(_impact_ratio(body, -1.0), rel=1e-13)
    # kinetic energy after over before, I_new e² / I_old: never above 1
    i_p, i_m = body.inertia_plus(), body.inertia_minus()
    assert i_m * e_p**2 / i_p <= 1.0 and i_p * e_m**2 / i_m <= 1.0
    if not body.symmetric:
        assert e_p != pytest.approx(e_m, rel=1e-6)


def test_housners_restitution_is_continuous_into_the_centred_block() -> None:
    body = Body(0.2, 0.8)
    near = Body(0.2, 0.8, b_cg=0.1 * (1 + 1e-9), h_cg=0.4 * (1 - 1e-9))
    assert near.housner_restitutions() == pytest.approx(body.housner_restitutions(), rel=1e-8)
    assert body.housner_restitutions()[0] == 1 - 1.5 * math.sin(body.alpha) ** 2


def test_a_measured_restitution_is_used_both_ways() -> None:
    assert resolve_restitutions(LOPSIDED, 0.8) == (0.8, 0.8)
    assert resolve_restitutions(LOPSIDED, "housner") == LOPSIDED.housner_restitutions()


# --------------------------------------------------------------------------------------------------
# the equations with an off-centre centre of mass, against an independent Newton–Euler solve


def test_stage_equations_with_each_corners_geometry_matchnewton_euler() -> None:
    rng = np.random.default_rng(24)
    for _ in range(300):
        b, h = rng.uniform(0.05, 1.0), rng.uniform(0.2, 2.0)
        body = Body(b=b, h=h, b_cg=rng.uniform(0.2, 0.8) * b, h_cg=rng.uniform(0.3, 0.7) * h)
        s = float(rng.choice([-1.0, 1.0]))
        alpha, r = (body.alpha_plus, body.r_plus) if s > 0 else (body.alpha_minus, body.r_minus)
        k, ig2 = r / (body.i_g**2 + r * r), body.i_g**2
        theta, omega = s * rng.uniform(0.0, 1.4), rng.uniform(-4.0, 4.0)
        gx, gz = plate_gravity(rng.uniform(-8, 8), rng.uniform(-5, 5), math.cos(0.1), math.sin(0.1))
        tdd, _, rt, rn = newton_euler(theta, omega, s, gx, gz, body)
        add = rocking_acceleration(theta, s, gx, gz, alpha, k)
        assert add == pytest.approx(tdd, rel=1e-9, abs=1e-9)
        assert pivot_reactions(theta, omega, add, s, gx, gz, alpha, r) == pytest.approx((rt, rn), rel=1e-9, abs=1e-9)
        slip, mu = float(rng.choice([-1.0, 1.0])), rng.uniform(0.05, 1.0)
        tdd, xdd, _, rn = newton_euler(theta, omega, s, gx, gz, body, slip, mu)
        got = rocking_sliding_acceleration(theta, omega, s, slip, gx, gz, alpha, r, ig2, mu)
        assert got == pytest.approx((tdd, xdd, rn), rel=1e-8, abs=1e-8)


def test_landing_on_either_corner_conserves_angular_momentum_about_it() -> None:
    rng = np.random.default_rng(25)
    for _ in range(300):
        b, h = rng.uniform(0.05, 1.0), rng.uniform(0.2, 2.0)
        body = Body(b=b, h=h, b_cg=rng.uniform(0.2, 0.8) * b, h_cg=rng.uniform(0.3, 0.7) * h)
        ig2 = body.i_g**2
        theta = rng.choice([-1, 1]) * rng.uniform(1e-3, 1.0)
        s = math.copysign(1.0, theta)
        alpha, r = (body.alpha_plus, body.r_plus) if s > 0 else (body.alpha_minus, body.r_minus)
        omega, v, w = rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(-3, 0.0)
        om_p = landing_omega(theta, omega, v, w, alpha, r, ig2)
        d = rot(theta) @ centre_from_pivot(body, s)
        v_cm = np.array([om_p * d[1], -om_p * d[0]])
        before = ig2 * (-omega) + d[0] * w - d[1] * v
        after = ig2 * (-om_p) + d[0] * v_cm[1] - d[1] * v_cm[0]
        assert after == pytest.approx(before, rel=1e-12, abs=1e-12)


# --------------------------------------------------------------------------------------------------
# Eq. 1 per side


@pytest.mark.parametrize("beta_deg", [0.0, 3.0, -2.0])
@pytest.mark.parametrize("a_v", [0.0, -0.3, 0.4])
def test_eq1_thresholds_per_side_in_closed_form(beta_deg: float, a_v: float) -> None:
    beta = math.radians(beta_deg)
    for body in (T5_1, LOPSIDED):
        a_plus, a_minus = uplift_thresholds(body, beta, a_v * G)
        tp, tm = body.d_plus / body.cg[1], body.d_minus / body.cg[1]
        tb = math.tan(beta)
        assert a_plus == pytest.approx((G + a_v * G) * (tp - tb) / (1 + tp * tb), rel=1e-12)
        assert a_minus == pytest.approx((G + a_v * G) * (tm + tb) / (1 - tm * tb), rel=1e-12)


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize(("side", "factor", "moves"), [(1, 0.999, False), (1, 1.001, True),
                                                       (-1, 0.999, False), (-1, 1.001, True)])
def test_each_side_starts_rocking_exactly_at_its_own_threshold(model: str, side: int, factor: float,
                                                               moves: bool) -> None:
    """A constant plate acceleration just below / above one side's Eq. 1 (uphill for +x rocking, downhill
    for −x), with a vertical component, on an inclined plate: rest / rocking on that side. LOPSIDED's two
    thresholds differ by a factor of about two, so the other side's threshold cannot be the one found."""
    body = LOPSIDED
    beta, a_v = math.radians(3.0), -0.2
    a_plus, a_minus = uplift_thresholds(body, beta, a_v * G)
    assert a_minus > 1.5 * a_plus
    a = (-a_plus if side > 0 else a_minus) * factor / G
    n = 100
    for solver in ("fast", "reference"):
        res = simulate(body, np.full(n, a), DT, beta=beta, acc_v=np.full(n, a_v), model=model, solver=solver,
                       friction=5.0, t_after=3.0, history=solver == "reference")
        assert (res.theta_max > 0) == moves, (solver, res)
        if moves:
            assert res.direction in (0, side)
            if solver == "reference":
                theta = np.asarray(res.trace.theta)
                assert np.all(side * theta >= -1e-15) and np.max(side * theta) > 1e-3  # (θ = 0 at impacts: to rounding)


def test_standing_range_is_minus_alpha_minus_to_alpha_plus() -> None:
    check_angle(LOPSIDED, 0.99 * LOPSIDED.alpha_plus)
    check_angle(LOPSIDED, -0.99 * LOPSIDED.alpha_minus)
    with pytest.raises(AnalysisInputError, match="alpha\\+"):
        check_angle(LOPSIDED, 1.01 * LOPSIDED.alpha_plus)
    with pytest.raises(AnalysisInputError, match="alpha-"):
        check_angle(LOPSIDED, -1.01 * LOPSIDED.alpha_minus)
    # a plate steeper than α+ but below α−: the block cannot stand facing downhill, but turned round it can
    beta = 0.5 * (LOPSIDED.alpha_plus + LOPSIDED.alpha_minus)
    with pytest.raises(AnalysisInputError):
        simulate(LOPSIDED, np.zeros(5), DT, beta=beta)
    assert simulate(LOPSIDED.mirrored(), np.zeros(5), DT, beta=beta).status == "rest"


# --------------------------------------------------------------------------------------------------
# the centred block recovered exactly


@pytest.mark.parametrize("model", ["rocking", "general"])
def test_a_centre_of_mass_given_at_the_centroid_changes_nothing(model: str) -> None:
    rng = np.random.default_rng(3)
    ah, av = _record(rng, 300, 0.6), _record(rng, 300, 0.8)
    plain, given = Body(0.15, 0.6), Body(0.15, 0.6, b_cg=0.075, h_cg=0.3)
    kw = dict(beta=0.05, restitution="housner", t_after=5.0)
    if model == "general":
        kw.update(acc_v=av, friction=0.4)
    for solver in ("fast", "reference"):
        a = simulate(plain, ah, DT, model=model, solver=solver, **kw)
        b = simulate(given, ah, DT, model=model, solver=solver, **kw)
        assert a.to_dict() == b.to_dict()
        if solver == "reference":
            assert a.trace.theta == b.trace.theta and a.trace.impacts == b.trace.impacts


# --------------------------------------------------------------------------------------------------
# mirror symmetry: the block turned round under the negated input


def _mirror_pair(model: str, solver: str, ah: np.ndarray, beta: float, **kw):
    a = simulate(LOPSIDED, ah, DT, beta=beta, model=model, solver=solver, **kw)
    b = simulate(LOPSIDED.mirrored(), -ah, DT, beta=-beta, model=model, solver=solver, **kw)
    return a, b


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize("beta", [0.0, 0.08])
@pytest.mark.parametrize("amp", [0.35, 0.9])
def test_the_block_turned_round_under_the_negated_input_mirrors_the_motion(model: str, beta: float,
                                                                          amp: float) -> None:
    ah = _record(np.random.default_rng(int(100 * amp)), 300, amp)
    kw = dict(restitution="housner", t_after=4.0)
    if model == "general":
        kw.update(friction=0.5, acc_v=_record(np.random.default_rng(7), 300, 0.6))
    fast = _mirror_pair(model, "fast", ah, beta, **kw)
    ref = _mirror_pair(model, "reference", ah, beta, history=True, **kw)
    for a, b in (fast, ref):
        assert b.direction == -a.direction and b.status == a.status and b.impacts == a.impacts
        assert b.theta_max == pytest.approx(a.theta_max, rel=1e-12)
        assert b.t_end == pytest.approx(a.t_end, rel=1e-12)
        assert b.slide_residual == pytest.approx(-a.slide_residual, rel=1e-9, abs=1e-15)
    a, b = ref
    assert a.theta_max > 1e-3  # it does rock
    np.testing.assert_allclose(b.trace.t, a.trace.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.trace.theta, -np.asarray(a.trace.theta), rtol=1e-10, atol=1e-13)
    # and the block itself is not mirror-symmetric: unmirrored, the negated input gives another motion
    c = simulate(LOPSIDED, -ah, DT, beta=-beta, model=model, solver="reference", **kw)
    assert c.theta_max != pytest.approx(a.theta_max, rel=1e-6)


# --------------------------------------------------------------------------------------------------
# free rocking: energy, the exact rate at impact, and the linearised closed form


def _rocking_energy(body: Body, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Energy per unit mass rocking on the corner sign θ: ½ I_s ω² + g z_G, z_G = R_s cos(α_s − |θ|)."""
    plus = theta >= 0.0
    r = np.where(plus, body.r_plus, body.r_minus)
    alpha = np.where(plus, body.alpha_plus, body.alpha_minus)
    return 0.5 * (body.i_g**2 + r * r) * omega**2 + G * r * np.cos(alpha - np.abs(theta))


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize("release", [1.0, -1.0])
def test_free_rocking_with_e1_keeps_each_sides_energy_and_amplitude(model: str, release: float) -> None:
    """e = 1 (ω kept through each impact): between impacts the energy ½ I_s ω² + g z_G is constant; every impact
    meets the block at |ω| = ω1 = √(2 g k_s (cos(α_s − θ0) − cos α_s)) (the release side s), because each
    side's motion is conservative and returns to θ = 0 at the speed it left; the other side's amplitude θ' then
    solves cos(α' − θ') = cos α' + ω1²/(2 g k'). At an impact the kinetic energy changes by I_new/I_old (the
    inertias about the two corners differ), and back on the first side it is what it was."""
    body = LOPSIDED
    s = release
    a_s, k_s = (body.alpha_plus, body.k_plus) if s > 0 else (body.alpha_minus, body.k_minus)
    a_o, k_o = (body.alpha_minus, body.k_minus) if s > 0 else (body.alpha_plus, body.k_plus)
    theta0 = s * (0.6 if s > 0 else 0.1) * a_s  # (from 0.14 α− on, it would overturn on the + side)
    omega1 = math.sqrt(2 * G * k_s * (math.cos(a_s - abs(theta0)) - math.cos(a_s)))
    other = a_o - math.acos(math.cos(a_o) + omega1**2 / (2 * G * k_o))
    kw = dict(model=model, restitution=1.0, theta0=theta0, t_after=6.0, friction=50.0)
    ref = simulate(body, np.zeros(3), DT, solver="reference", history=True, **kw)
    impacts = ref.trace.impacts
    assert len(impacts) >= 8
    for _, om_minus, om_plus in impacts:
        assert abs(om_minus) == pytest.approx(omega1, rel=1e-8)
        assert om_plus == om_minus
    assert ref.theta_max == pytest.approx(max(abs(theta0), other), rel=1e-8)
    th, om = np.asarray(ref.trace.theta), np.asarray(ref.trace.omega)
    energy = _rocking_energy(body, th, om)
    for side, value in ((s, _rocking_energy(body, np.array([theta0]), np.array([0.0]))[0]),
                        (-s, 0.5 * (body.i_g**2 + (body.r_minus if s > 0 else body.r_plus) ** 2) * omega1**2
                         + G * body.cg[1])):
        on = side * th > 1e-9
        np.testing.assert_allclose(energy[on], value, rtol=1e-9)
    fast = simulate(body, np.zeros(3), DT, solver="fast", **kw)
    assert fast.theta_max == pytest.approx(ref.theta_max, rel=1e-5)
    assert abs(other - abs(theta0)) > 0.01  # the two sides' amplitudes do differ


def test_housners_impacts_per_direction_in_free_rocking() -> None:
    """restitution="housner": the impact that ends rocking on the + corner multiplies ω by e+, the next (ending
    on the − corner) by e−; between impacts the motion is conservative, so |ω| at the n-th impact is ω1 times the
    product of the ratios before it."""
    body = LOPSIDED
    e_p, e_m = body.housner_restitutions()
    theta0 = 0.8 * body.alpha_plus
    omega1 = math.sqrt(2 * G * body.k_plus * (math.cos(body.alpha_plus - theta0) - math.cos(body.alpha_plus)))
    for model in ("rocking", "general"):
        ref = simulate(body, np.zeros(3), DT, model=model, solver="reference", restitution="housner", theta0=theta0,
                       t_after=20.0, friction=50.0)
        speed = omega1
        for n, (_, om_minus, om_plus) in enumerate(ref.trace.impacts[:6]):
            ratio = e_p if n % 2 == 0 else e_m
            assert abs(om_minus) == pytest.approx(speed, rel=1e-8)
            assert om_plus == pytest.approx(ratio * om_minus, rel=1e-13)
            speed *= ratio
        assert ref.status == "rest"


def test_linearised_free_rocking_in_closed_form_on_each_side() -> None:
    """Housner's linearised rocking, side s: θ'' = p_s² (θ − s α_s). Released at rest at θ0 on the + side it
    reaches θ = 0 at t1 = arccosh(α+/(α+ − θ0))/p+ with |ω1| = p+ √(α+² − (α+ − θ0)²); on the − side, starting at
    e+|ω1|, it comes back after 2 artanh(e+|ω1|/(p− α−))/p−, then on the + side after
    2 artanh(e− e+ |ω1|/(p+ α+))/p+."""
    body = LOPSIDED
    e_p, e_m = body.housner_restitutions()
    a_p, a_m, p_p, p_m = body.alpha_plus, body.alpha_minus, body.p_plus, body.p_minus
    theta0 = 0.5 * a_p
    t1 = math.acosh(a_p / (a_p - theta0)) / p_p
    om1 = p_p * math.sqrt(a_p**2 - (a_p - theta0) ** 2)
    t2 = t1 + 2 * math.atanh(e_p * om1 / (p_m * a_m)) / p_m
    t3 = t2 + 2 * math.atanh(e_m * e_p * om1 / (p_p * a_p)) / p_p
    ref = simulate(body, np.zeros(3), DT, solver="reference", linearised=True, restitution="housner", theta0=theta0,
                   t_after=10.0)
    times = [imp[0] for imp in ref.trace.impacts[:3]]
    assert times == pytest.approx([t1, t2, t3], rel=1e-8)
    assert ref.trace.impacts[0][1] == pytest.approx(-om1, rel=1e-8)
    assert ref.trace.impacts[1][1] == pytest.approx(e_p * om1, rel=1e-8)  # coming back from the − side


# --------------------------------------------------------------------------------------------------
# the general model in free motion: energy never grows


def _general_energy(body: Body, tr) -> np.ndarray:
    """Mechanical energy per unit mass relative to the level plate: on a pivot s the centre of mass moves with
    the pivot's v plus ω × R_s (R_s, α_s the pivot's); in flight (v, w) and z are the trace's."""
    th, om, v = np.asarray(tr.theta), np.asarray(tr.omega), np.asarray(tr.v)
    st, piv = np.asarray(tr.stage), np.asarray(tr.pivot)
    plus = piv > 0
    r = np.where(plus, body.r_plus, body.r_minus)
    alpha = np.where(plus, body.alpha_plus, body.alpha_minus)
    psi = alpha - np.abs(th)
    on_pivot = (st == ST_ROCK) | (st == ST_ROCKSLIDE)
    vx = np.where(on_pivot, v + r * om * np.cos(psi), v)
    vz = np.where(on_pivot, piv * r * om * np.sin(psi), np.asarray(tr.w))
    z = np.where(on_pivot, r * np.cos(psi), np.asarray(tr.z))
    return 0.5 * (vx**2 + vz**2) + 0.5 * body.i_g**2 * om**2 + G * z


@pytest.mark.parametrize("e", [0.0, "housner"])
def test_general_free_motion_of_an_off_centre_block_never_gains_energy(e) -> None:
    seen: set[int] = set()
    for body, th0, om0, mu in [(LOPSIDED, 0.1, 0.0, 0.15), (LOPSIDED, -0.3, 3.0, 0.3),
                               (LOPSIDED.mirrored(), 0.3, -12.0, 0.3), (Body(0.2, 0.4, b_cg=0.07, h_cg=0.22), 0.05,
                                                                        -7.0, 0.3)]:
        res = simulate(body, np.zeros(3), DT, model="general", solver="reference", restitution=e, friction=mu,
                       t_after=6.0, theta0=th0, omega0=om0, history=True)
        assert res.status in ("rest", "overturned")
        energy = _general_energy(body, res.trace)
        assert np.max(np.diff(energy)) <= 1e-9 * energy[0]
        seen |= set(res.trace.stage)
        fast = simulate(body, np.zeros(3), DT, model="general", restitution=e, friction=mu, t_after=6.0, theta0=th0,
                        omega0=om0)
        assert (fast.status, fast.direction) == (res.status, res.direction)
        assert fast.t_end == pytest.approx(res.t_end, abs=1e-3)
    assert {ST_ROCK, ST_ROCKSLIDE, ST_FLIGHT} <= seen


# --------------------------------------------------------------------------------------------------
# the fast engine against the reference on random off-centre scenes


def _random_asymmetric_scene(seed: int, model: str) -> tuple[Body, np.ndarray, dict]:
    rng = np.random.default_rng(seed)
    b, h = rng.uniform(0.1, 0.4), rng.uniform(0.4, 1.2)
    body = Body(b=b, h=h, b_cg=rng.uniform(0.3, 0.7) * b, h_cg=rng.uniform(0.4, 0.6) * h)
    ah = _record(rng, 300, rng.uniform(0.2, 0.8))
    beta = rng.uniform(-0.8, 0.8) * (body.alpha_plus if rng.uniform() < 0.5 else body.alpha_minus)
    beta = min(max(beta, -0.8 * body.alpha_minus), 0.8 * body.alpha_plus)
    kw = dict(beta=beta, restitution=["housner", 0.0, 0.6][seed % 3], t_after=3.0, model=model)
    if model == "general":
        kw.update(friction=rng.uniform(0.3, 0.8), acc_v=_record(rng, 300, rng.uniform(0.3, 1.6)))
    return body, ah, kw


@pytest.mark.parametrize("model", ["rocking", "general"])
def test_fast_engine_agrees_with_the_reference_on_random_off_centre_scenes(model: str) -> None:
    compared = overturned = 0
    for seed in range(16):
        body, ah, kw = _random_asymmetric_scene(2400 + seed, model)
        fast = simulate(body, ah, DT, **kw)
        finer = simulate(body, ah, DT, step=0.0125, **kw)
        if (fast.direction, fast.status) != (finer.direction, finer.status) or (
                fast.t_overturn is not None and abs(fast.t_overturn - finer.t_overturn) > 1e-4):
            continue  # sensitive to the step: chaotic, not a comparison
        ref = simulate(body, ah, DT, solver="reference", **kw)
        compared += 1
        assert (fast.direction, fast.status) == (ref.direction, ref.status), seed
        if ref.t_overturn is not None:
            overturned += 1
            assert fast.t_overturn == pytest.approx(ref.t_overturn, abs=1e-3), seed
        else:
            assert fast.theta_max == pytest.approx(ref.theta_max, rel=1e-3, abs=1e-6), seed
            assert fast.t_end == pytest.approx(ref.t_end, abs=1e-3), seed
        if kw["restitution"] == 0.0:
            assert fast.impacts == ref.impacts, seed
    assert compared >= 12 and overturned >= 2
