"""Properties that must hold for every record, body and angle (VALIDATION.md, second part).

Inputs are generated with hypothesis: short piecewise-linear records (100–600 samples, dt 5–20 ms,
peak up to 1 g: sums of sines, smoothed noise or a few pulses, from a hypothesis-drawn seed),
uniform blocks with b/h in [0.1, 0.5] and h in [0.1, 2] m, plate angles β in [0, 0.8·α).
The fast engine carries most examples, the reference a few. Expected values come from symmetry,
Eq. 1, the sign convention of docs/architecture.md §2 and the order of the fast engine's method (RK4,
events on the step's cubic Hermite interpolant: order 4) — never from earlier output of the code.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from analysis import AnalysisInputError, Body, exceeds_threshold, simulate
from analysis.body import G

FEW = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SOME = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])

RESTITUTIONS = st.sampled_from([0.0, "housner", 0.5])


# ------------------------------------------------------------------------------------ strategies


@st.composite
def records(draw, max_amp: float = 1.0) -> tuple[np.ndarray, float]:
    """(acc_h [g], dt [s]): a short random record, tapered to zero at both ends."""
    n = draw(st.integers(100, 600))
    dt = draw(st.floats(0.005, 0.02))
    amp = draw(st.floats(0.02, max_amp))
    kind = draw(st.sampled_from(["sines", "noise", "pulses"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    t = np.arange(n) * dt
    dur = t[-1]
    if kind == "sines":
        acc = sum(rng.normal() * np.sin(2 * np.pi * rng.uniform(0.3, 8.0) * t + rng.uniform(0, 2 * np.pi))
                  for _ in range(rng.integers(1, 5)))
    elif kind == "noise":
        width = int(rng.integers(3, 16))
        acc = np.convolve(rng.normal(size=n + width), np.ones(width) / width, mode="valid")[:n]
    else:
        acc = np.zeros(n)
        for _ in range(rng.integers(1, 4)):
            t0, w = rng.uniform(0, 0.8 * dur), rng.uniform(0.05, 0.5) * dur
            inside = (t >= t0) & (t <= t0 + w)
            acc[inside] += rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 1.0) * np.sin(np.pi * (t[inside] - t0) / w)
    acc = np.asarray(acc, dtype=float) * np.sqrt(np.abs(np.sin(np.pi * t / dur)))
    peak = np.max(np.abs(acc))
    if peak == 0.0:
        acc = np.sin(np.pi * t / dur)
        peak = 1.0
    return acc * (amp / peak), dt


@st.composite
def bodies(draw) -> Body:
    aspect = draw(st.floats(0.1, 0.5))
    h = draw(st.floats(0.1, 2.0))
    return Body(b=aspect * h, h=h)


@st.composite
def scenes(draw, max_amp: float = 1.0) -> tuple[Body, np.ndarray, float, float]:
    """(body, acc_h [g], dt, beta) with β in [0, 0.8·α)."""
    body = draw(bodies())
    acc, dt = draw(records(max_amp))
    beta = draw(st.floats(0.0, 0.8, exclude_max=True)) * body.alpha
    return body, acc, dt, beta


def _describe(body: Body, acc: np.ndarray, dt: float, beta: float, **kw) -> str:
    return (f"Body(b={body.b!r}, h={body.h!r}), beta={beta!r}, dt={dt!r}, n={acc.size}, "
            f"peak={np.max(np.abs(acc)):.4f} g, {kw}, acc={np.array2string(acc, precision=17, threshold=10**6)}")


# ------------------------------------------------------------------------------- mirror symmetry


def _assert_mirrored(a, b, rel: float) -> None:
    assert b.direction == -a.direction
    assert b.status == a.status
    assert b.impacts == a.impacts
    assert b.theta_max == pytest.approx(a.theta_max, rel=rel, abs=1e-300)
    assert b.t_end == pytest.approx(a.t_end, rel=rel, abs=1e-300)
    if a.t_overturn is None:
        assert b.t_overturn is None
    else:
        assert b.t_overturn == pytest.approx(a.t_overturn, rel=rel)


@SOME
@given(scene=scenes(), e=RESTITUTIONS)
def test_mirror_symmetry_fast(scene, e) -> None:
    """Record negated and β → −β: the mirrored outcome (direction flips, same θ_max, t_overturn)."""
    body, acc, dt, beta = scene
    a = simulate(body, acc, dt, beta=beta, restitution=e)
    b = simulate(body, -acc, dt, beta=-beta, restitution=e)
    note(f"{a}\n{b}")
    _assert_mirrored(a, b, rel=1e-12)


@FEW
@given(scene=scenes(), e=RESTITUTIONS)
def test_mirror_symmetry_reference(scene, e) -> None:
    body, acc, dt, beta = scene
    a = simulate(body, acc, dt, beta=beta, restitution=e, solver="reference")
    b = simulate(body, -acc, dt, beta=-beta, restitution=e, solver="reference")
    note(f"{a}\n{b}")
    _assert_mirrored(a, b, rel=1e-9)


@pytest.mark.parametrize("solver", ["fast", "reference"])
def test_mirror_symmetry_nontrivial_case(solver: str) -> None:
    """A fixed case that does overturn, so that the mirror property is exercised with direction ≠ 0."""
    body = Body(b=0.2, h=1.0)
    t = np.arange(300) * 0.01
    acc = -0.5 * np.sin(2 * np.pi * 0.7 * t) * np.sin(np.pi * t / t[-1])
    a = simulate(body, acc, 0.01, beta=0.05, solver=solver)
    b = simulate(body, -acc, 0.01, beta=-0.05, solver=solver)
    assert a.direction != 0
    _assert_mirrored(a, b, rel=1e-9)


@SOME
@given(body=bodies(), rec=records(), e=RESTITUTIONS)
def test_level_plane_negated_record_flips_direction(body, rec, e) -> None:
    """β = 0: negating the record flips every direction (fast; the reference on a few below)."""
    acc, dt = rec
    a = simulate(body, acc, dt, restitution=e)
    b = simulate(body, -acc, dt, restitution=e)
    assert b.direction == -a.direction
    assert b.theta_max == pytest.approx(a.theta_max, rel=1e-12, abs=1e-300)


@FEW
@given(body=bodies(), rec=records())
def test_level_plane_negated_record_flips_direction_reference(body, rec) -> None:
    acc, dt = rec
    a = simulate(body, acc, dt, solver="reference")
    b = simulate(body, -acc, dt, solver="reference")
    assert b.direction == -a.direction
    assert b.theta_max == pytest.approx(a.theta_max, rel=1e-9, abs=1e-300)


# -------------------------------------------------------------------------- Eq. 1: the pre-screen


def _scaled_to_threshold(body: Body, acc: np.ndarray, beta: float, factor: float) -> np.ndarray:
    """The record scaled so that its largest excursion, relative to Eq. 1's threshold on its side
    (uphill a_x < 0 against tan(α − β), downhill against tan(α + β), in g), is ``factor``."""
    up = np.max(-acc) / math.tan(body.alpha - beta)
    down = np.max(acc) / math.tan(body.alpha + beta)
    return acc * (factor / max(up, down))


@SOME
@given(scene=scenes(), factor=st.floats(0.05, 0.999))
def test_record_below_eq1_leaves_body_at_rest(scene, factor) -> None:
    """A record that never reaches Eq. 1 leaves the body at rest (θ ≡ 0) after one scan."""
    body, acc, dt, beta = scene
    acc = _scaled_to_threshold(body, acc, beta, factor)
    assert not exceeds_threshold(body, beta, acc * G)
    res = simulate(body, acc, dt, beta=beta)
    assert res.theta_max == 0.0
    assert res.prescreened is True
    assert (res.direction, res.status, res.impacts, res.t_end) == (0, "rest", 0, 0.0)


@FEW
@given(scene=scenes(), factor=st.floats(0.05, 0.999))
def test_record_below_eq1_leaves_body_at_rest_reference(scene, factor) -> None:
    body, acc, dt, beta = scene
    acc = _scaled_to_threshold(body, acc, beta, factor)
    assert not exceeds_threshold(body, beta, acc * G)
    res = simulate(body, acc, dt, beta=beta, solver="reference")
    assert res.theta_max == 0.0
    assert (res.direction, res.status, res.impacts) == (0, "rest", 0)


@SOME
@given(scene=scenes(), factor=st.floats(1.001, 3.0))
def test_record_above_eq1_moves_the_body(scene, factor) -> None:
    """The converse (so that the pre-screen test can fail): beyond Eq. 1 the body does rock."""
    body, acc, dt, beta = scene
    acc = _scaled_to_threshold(body, acc, beta, factor)
    assert exceeds_threshold(body, beta, acc * G)
    res = simulate(body, acc, dt, beta=beta)
    assert res.prescreened is False
    assert res.theta_max > 0.0


# ------------------------------------------------------------------------------ sign convention

SLENDER = [Body(b=0.2, h=1.0), Body(b=0.1, h=0.5), Body(b=0.3, h=1.5), Body(b=0.06, h=0.4)]


def _general_or_skip(solver: str) -> dict:
    pytest.importorskip("analysis.reference_general" if solver == "reference" else "analysis.fast_general")
    return {"model": "general", "friction": 50.0}


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize("solver", ["fast", "reference"])
@pytest.mark.parametrize("beta_frac", [0.0, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("body", SLENDER, ids=lambda b: b.label())
def test_sign_convention_long_plate_acceleration(body: Body, beta_frac: float, solver: str, model: str) -> None:
    """docs/architecture.md §2: a long uphill plate acceleration (a_x < 0) of 0.5 g tips a slender body
    towards +x (direction +1, downhill); the same downhill tips it towards −x (−1)."""
    kw = _general_or_skip(solver) if model == "general" else {}
    beta = beta_frac * body.alpha
    assert math.tan(body.alpha + beta) < 0.5  # 0.5 g exceeds Eq. 1 on both sides: the body must go
    acc = np.full(401, 0.5)
    uphill = simulate(body, -acc, 0.01, beta=beta, solver=solver, **kw)
    downhill = simulate(body, acc, 0.01, beta=beta, solver=solver, **kw)
    assert (uphill.status, uphill.direction) == ("overturned", 1)
    assert (downhill.status, downhill.direction) == ("overturned", -1)


# -------------------------------------------------------------------------------- convergence

ORDER_STEPS = (8, 16, 32)
"""Steps per reference event time T: p·h = p·T/N. Asymptotic for RK4 here, and the smallest error
(≳1e-9 s) stays well above the reference's (~1e-12 s)."""


def _orders(errors: list[float]) -> list[float]:
    return [math.log2(abs(a / b)) for a, b in itertools.pairwise(errors)]


def _free_fall_case(body: Body, beta: float, frac: float, side: float):
    """Release at rest on pivot ``side`` at frac·(α ∓ β) (below the static limit): it falls back."""
    theta0 = side * frac * (body.alpha - side * beta)
    ref = simulate(body, np.zeros(2), 0.01, beta=beta, theta0=theta0, solver="reference")
    assert ref.status == "rest" and len(ref.trace.impacts) == 1
    return theta0, ref.t_end


@pytest.mark.parametrize("model", ["rocking", "general"])
@FEW
@given(body=bodies(), beta_frac=st.floats(0.0, 0.8), frac=st.floats(0.2, 0.9), side=st.sampled_from([1.0, -1.0]))
def test_convergence_order_free_rocking(model, body, beta_frac, frac, side) -> None:
    """The fast engine's error in the first impact time shrinks at order ≈ 4 as p·h halves.

    The grid is aligned so that the impact falls on a step boundary (dt = h = T/N), which isolates
    the integrator (RK4, order 4) from the position of the event inside its step (see the
    mid-step test below)."""
    kw = _general_or_skip("fast") if model == "general" else {}
    beta = beta_frac * body.alpha
    theta0, t_ref = _free_fall_case(body, beta, frac, side)
    errors = []
    for n in ORDER_STEPS:
        dt = t_ref / n
        res = simulate(body, np.zeros(2), dt, beta=beta, theta0=theta0, step=body.p * dt * (1 + 1e-12), **kw)
        errors.append(res.t_end - t_ref)
    note(f"errors {errors}, orders {_orders(errors)}")
    for order in _orders(errors):
        assert 3.0 <= order <= 5.5


@FEW
@given(body=bodies(), beta_frac=st.floats(0.0, 0.8), amp=st.floats(1.2, 3.0))
def test_convergence_order_forced(body, beta_frac, amp) -> None:
    """Forced: constant uphill plate acceleration amp × Eq. 1's threshold on a tilted plate; error
    of the (static-criterion) overturn time at order ≈ 4 as p·h halves (grid aligned as above;
    a constant record is the same piecewise-linear input on every grid)."""
    beta = beta_frac * body.alpha
    a = -amp * math.tan(body.alpha - beta)
    ref = simulate(body, np.full(4000, a), 0.01, beta=beta, criterion="static", solver="reference")
    assert ref.status == "overturned" and ref.direction == 1
    t_ref = ref.t_overturn
    errors = []
    for n in ORDER_STEPS:
        dt = t_ref / n
        res = simulate(body, np.full(2 * n, a), dt, beta=beta, criterion="static",
                       step=body.p * dt * (1 + 1e-12))
        assert res.direction == 1
        errors.append(res.t_overturn - t_ref)
    note(f"errors {errors}, orders {_orders(errors)}")
    for order in _orders(errors):
        assert 3.0 <= order <= 5.5


@pytest.mark.parametrize("model", ["rocking", "general"])
@pytest.mark.parametrize("frac", [0.25, 0.5])
def test_convergence_order_impact_inside_a_step(frac: float, model: str) -> None:
    """V2's first impact with the grid placed so that the impact lies at ``frac`` of a step from
    its end: RK4 + cubic Hermite location must still converge at order ≈ 4 (the general model
    with μ very high rocks like Eq. 2 and shows the same 3rd order)."""
    kw = _general_or_skip("fast") if model == "general" else {}
    body = Body.from_p_alpha(2.0, 0.2)
    t_ref = simulate(body, np.zeros(2), 0.01, theta0=0.1, solver="reference").t_end
    errors = []
    for n in ORDER_STEPS:
        dt = t_ref / (n - frac)
        res = simulate(body, np.zeros(2), dt, theta0=0.1, step=body.p * dt * (1 + 1e-12), **kw)
        errors.append(res.t_end - t_ref)
    print("errors", errors, "orders", _orders(errors))
    for order in _orders(errors):
        assert 3.5 <= order <= 5.5


# ------------------------------------------------------------------------ fast against reference


def _reference_direction(body: Body, acc: np.ndarray, dt: float, beta: float, e) -> int:
    return simulate(body, acc, dt, beta=beta, restitution=e, solver="reference").direction


@SOME
@given(scene=scenes(), e=RESTITUTIONS)
def test_fast_agrees_with_reference_on_direction(scene, e) -> None:
    """The fast engine (default step) and the reference agree on the overturn direction. A
    disagreement is accepted only on a knife edge: when a 1e-6 relative change of the record's
    scale flips the reference too (the case is printed)."""
    body, acc, dt, beta = scene
    fast = simulate(body, acc, dt, beta=beta, restitution=e)
    ref = _reference_direction(body, acc, dt, beta, e)
    if fast.direction == ref:
        return
    perturbed = {_reference_direction(body, acc * (1 + s * 1e-6), dt, beta, e) for s in (-1, 1)}
    case = _describe(body, acc, dt, beta, restitution=e)
    print(f"fast/reference disagree: fast {fast.direction}, reference {ref}, perturbed reference "
          f"{sorted(perturbed)}; {case}")
    assert perturbed != {ref}, f"fast {fast.direction} vs reference {ref} (not a knife edge): {case}"


# ---------------------------------------------------------------------------------- robustness


@FEW
@given(body=bodies(), theta_frac=st.floats(0.05, 0.95), e=st.floats(0.0, 0.95),
       side=st.sampled_from([1.0, -1.0]))
def test_free_motion_never_gains_energy(body, theta_frac, e, side) -> None:
    """Free rocking on a level plane, restitution in [0, 0.95]: |θ| never exceeds the release
    angle, and the motion ends at rest (no hang, no NaN)."""
    theta0 = side * theta_frac * body.alpha
    for solver in ("fast", "reference"):
        res = simulate(body, np.zeros(2), 0.01, theta0=theta0, restitution=e, solver=solver, t_after=200.0)
        assert res.theta_max <= abs(theta0) * (1 + 1e-9)
        assert res.direction == 0
        assert math.isfinite(res.t_end)
        assert res.status == "rest"


# ---------------------------------------------------------------------------------- bad input

GOOD = Body(b=0.2, h=1.0)
ACC = np.array([0.0, 0.1, -0.1, 0.0])


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"beta": GOOD.alpha}, ["beta", "alpha"]),
    ({"beta": 1.5 * GOOD.alpha}, ["beta", "alpha"]),
    ({"beta": -GOOD.alpha}, ["beta", "alpha"]),
    ({"beta": math.nan}, ["beta"]),
    ({"acc_h": np.array([0.0, math.nan, 0.1])}, ["acc_h", "nan"]),
    ({"acc_h": np.array([0.0, math.inf, 0.1])}, ["acc_h", "inf"]),
    ({"acc_h": np.array([0.0, 0.1, -math.inf])}, ["acc_h", "inf"]),
    ({"acc_h": np.array([])}, ["acc_h", "empty"]),
    ({"acc_h": []}, ["acc_h", "empty"]),
    ({"acc_v": np.array([0.0, math.nan, 0.0, 0.0])}, ["acc_v", "nan"]),
    ({"acc_v": np.zeros(3)}, ["acc_v", "samples"]),
    ({"dt": 0.0}, ["dt"]),
    ({"dt": -0.01}, ["dt"]),
    ({"dt": math.nan}, ["dt"]),
    ({"dt": None}, ["dt"]),
    ({"model": "sliding"}, ["model"]),
    ({"solver": "euler"}, ["solver"]),
    ({"restitution": 1.5}, ["restitution"]),
    ({"restitution": "bouncy"}, ["restitution"]),
    ({"friction": 0.0}, ["friction"]),
    ({"criterion": "tipping"}, ["criterion"]),
    ({"linearised": True, "solver": "fast"}, ["linearised"]),
    ({"linearised": True, "solver": "reference", "model": "general"}, ["linearised"]),
    ({"times": [0.0, 0.1, 0.2, 0.3], "solver": "fast"}, ["times"]),
    ({"times": [0.0, 0.2, 0.1, 0.3], "solver": "reference"}, ["times"]),
    ({"times": [0.0, 0.1, 0.2], "solver": "reference"}, ["times"]),
])
def test_bad_input_is_refused_with_a_clear_message(kwargs: dict, words: list[str]) -> None:
    """Bad input → AnalysisInputError whose message names the problem (both solvers unless the
    case is about one of them)."""
    for solver in [kwargs["solver"]] if "solver" in kwargs else ["fast", "reference"]:
        args = {"body": GOOD, "acc_h": ACC, "dt": 0.01, "solver": solver, **kwargs}
        with pytest.raises(AnalysisInputError) as info:
            simulate(**args)
        message = str(info.value).lower()
        for word in words:
            assert word in message, f"{word!r} not in {message!r}"


@pytest.mark.parametrize(("b", "h", "word"), [
    (0.0, 1.0, "b"), (-0.1, 1.0, "b"), (math.nan, 1.0, "b"), (math.inf, 1.0, "b"),
    (0.2, 0.0, "h"), (0.2, -1.0, "h"), (0.2, math.nan, "h"),
])
def test_bad_body_is_refused(b: float, h: float, word: str) -> None:
    with pytest.raises(AnalysisInputError) as info:
        Body(b=b, h=h)
    assert f"{word} must" in str(info.value)


@pytest.mark.parametrize(("p", "alpha"), [(0.0, 0.2), (-1.0, 0.2), (2.0, 0.0), (2.0, math.pi / 2)])
def test_bad_p_alpha_is_refused(p: float, alpha: float) -> None:
    with pytest.raises(AnalysisInputError, match="p > 0 and 0 < alpha"):
        Body.from_p_alpha(p, alpha)
