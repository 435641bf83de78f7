"""``simulate``: one body, one record, one angle — like scipy's ``solve_ivp``, methods by name.

Units at this interface (docs/architecture.md §7): accelerations in **g** (horizontal positive towards the
downhill side +x, vertical positive up), ``dt`` in s, ``beta`` in rad (> 0: plate descends towards
+x). ``direction`` is +1 for an overturn towards the low side (the controlled, desired side), −1
towards the high side, 0 for none.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike

from analysis.body import Body, G
from analysis.errors import AnalysisInputError

if TYPE_CHECKING:  # the reference solvers (and scipy) are imported only when solver="reference" runs
    from analysis.reference import Trace

Model = Literal["rocking", "general"]
Solver = Literal["fast", "reference"]
Criterion = Literal["fall", "static"]

DEFAULT_FRICTION = 1.0
"""Default friction coefficient of the general model: high, so that the block rocks rather than
slides, as in the paper's analytical study."""

DEFAULT_STEP = 0.05
"""Default step of the fast engine as p·h (dimensionless): the RK4 step is at most this over p."""


@dataclass(frozen=True)
class SimulationResult:
    """The outcome of one scene."""

    direction: int
    """+1 overturned towards the low side (+x), −1 towards the high side, 0 did not overturn."""
    t_overturn: float | None
    """Time the overturn criterion was reached [s], or None."""
    theta_max: float
    """Largest |θ| relative to the plate [rad]."""
    status: str
    """``overturned``, ``rest`` (the motion ended at rest) or ``undecided`` (still moving ``t_after``
    seconds after the record)."""
    t_end: float
    """Overturn time, or when the body last came to rest [s] (0 if it never moved)."""
    impacts: int
    """Number of impacts (corner changes) counted."""
    model: str
    solver: str
    prescreened: bool = False
    """True when Eq. 1's pre-screen alone settled the scene (the body never left rest)."""
    slide_peak: float = 0.0
    """General model: largest |u| [m], u the slide displacement along +x (downhill) relative to the
    plate — where the base centre lies once the block is laid flat about the corner it leans on
    (docs/general-model.md, *Slide displacement*). The rocking model does not slide: 0."""
    slide_residual: float = 0.0
    """General model: u when the motion ended (rest, overturn or the end of ``t_after``) [m]."""
    slide_time: float = 0.0
    """General model: how long the base (SLIDE) or the pivot (ROCKSLIDE) slid [s]."""
    trace: Trace | None = None
    """Reference solver only: impacts and, with ``history=True``, the time history."""

    def to_dict(self) -> dict:
        """JSON-ready fields (without the trace)."""
        d = asdict(self)
        d.pop("trace")
        return d


def resolve_restitutions(body: Body, restitution: float | str) -> tuple[float, float]:
    """(e+, e−): the angular-velocity ratio at an impact that ends rocking on the +x corner, and on the −x corner.
    ``"housner"``: Housner's, from angular momentum about the landing corner (``Body.housner_restitutions``: the two
    differ when the centre of mass is off the middle); a number in [0, 1] (a measured restitution) is used both
    ways, as given."""
    if isinstance(restitution, str) and restitution.lower() == "housner":
        return body.housner_restitutions()
    e = resolve_restitution(body, restitution)
    return e, e


def resolve_restitution(body: Body, restitution: float | str) -> float:
    """A number in [0, 1], or ``"housner"`` for 1 − 1.5 sin²α (a body whose two impacts are alike; else
    :func:`resolve_restitutions`)."""
    if isinstance(restitution, str):
        if restitution.lower() == "housner":
            return body.housner_restitution()
        try:
            restitution = float(restitution)
        except ValueError:
            raise AnalysisInputError(
                f"restitution {restitution!r}: expected a number in [0, 1] or 'housner'"
            ) from None
    if not (0.0 <= restitution <= 1.0):
        raise AnalysisInputError(f"restitution must be in [0, 1], got {restitution}")
    return float(restitution)


def check_angle(body: Body, beta: float) -> None:
    """The body must be able to stand on the plate: −α− < β < α+ (|β| < α for a symmetric body)."""
    if not math.isfinite(beta):
        raise AnalysisInputError(f"angle beta must be finite, got {beta}")
    if body.symmetric:
        if abs(beta) >= body.alpha_plus:
            raise AnalysisInputError(
                f"body {body.label()} cannot stand at beta = {math.degrees(beta):.3f} deg: "
                f"|beta| must be below its slenderness alpha = {math.degrees(body.alpha_plus):.3f} deg"
            )
    elif not -body.alpha_minus < beta < body.alpha_plus:
        raise AnalysisInputError(
            f"body {body.label()} cannot stand at beta = {math.degrees(beta):.3f} deg: beta must be below its "
            f"slenderness towards +x (downhill), alpha+ = {math.degrees(body.alpha_plus):.3f} deg, and above minus "
            f"its slenderness towards -x, -alpha- = {-math.degrees(body.alpha_minus):.3f} deg"
        )


def check_record(acc: ArrayLike, name: str) -> np.ndarray:
    """A finite, non-empty 1-D float array, or a clear error naming the array and the sample."""
    arr = np.asarray(acc, dtype=float)
    if arr.ndim != 1 or arr.size == 0:
        raise AnalysisInputError(f"{name}: expected a non-empty 1-D array of accelerations, got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise AnalysisInputError(f"{name}: sample {bad[0]} is {arr[bad[0]]} (NaN/inf); {bad.size} bad samples")
    return arr


def check_dt(dt: float | None) -> float:
    if dt is None or not math.isfinite(dt) or dt <= 0:
        raise AnalysisInputError(f"dt must be a finite time step > 0 s, got {dt}")
    return float(dt)


def fall_angles(body: Body, beta: float, criterion: Criterion) -> tuple[float, float]:
    """|θ| counted as overturned towards +x and −x: π/2 (the body falls), or the static criterion:
    the centre of mass passes over the pivot, α+ − β downhill and α− + β uphill."""
    if criterion == "fall":
        return 0.5 * math.pi, 0.5 * math.pi
    if criterion == "static":
        return body.alpha_plus - beta, body.alpha_minus + beta
    raise AnalysisInputError(f"criterion must be 'fall' or 'static', got {criterion!r}")


def substeps(body: Body, dt: float, step: float) -> int:
    """RK4 steps per sample interval so that p·h ≤ ``step`` on either corner (p the larger of p±)."""
    if not (step > 0 and math.isfinite(step)):
        raise AnalysisInputError(f"step (p·h) must be > 0, got {step}")
    return max(1, math.ceil(max(body.p_plus, body.p_minus) * dt / step - 1e-9))


def simulate(
    body: Body,
    acc_h: ArrayLike,
    dt: float | None = None,
    beta: float = 0.0,
    acc_v: ArrayLike | None = None,
    model: Model = "rocking",
    solver: Solver = "fast",
    restitution: float | str = 0.0,
    *,
    friction: float = DEFAULT_FRICTION,
    criterion: Criterion = "fall",
    t_after: float = 60.0,
    theta0: float = 0.0,
    omega0: float = 0.0,
    times: ArrayLike | None = None,
    linearised: bool = False,
    history: bool = False,
    step: float = DEFAULT_STEP,
) -> SimulationResult:
    """Response of ``body`` on a plate inclined by ``beta`` to the record ``acc_h`` [g] (and ``acc_v``).

    ``model``: ``"rocking"`` (Eq. 2) or ``"general"`` (Eqs. 3–10, friction ``friction``).
    ``solver``: ``"fast"`` (compiled RK4, step p·h ≤ ``step``) or ``"reference"`` (DOP853, exact events).
    ``restitution``: angular-velocity ratio at impact; 0 = plastic (paper), ``"housner"`` (per impact direction
    for a body whose centre of mass is off the middle: ``Body.housner_restitutions``) or a number (both ways).
    ``criterion``: ``"fall"`` (|θ| reaches π/2) or ``"static"`` (passing α ∓ β).
    ``t_after``: seconds of free motion followed after the record (zero input) before giving up.
    ``theta0``/``omega0``: initial rotation [rad] and rate [rad/s] (free-rocking studies).
    ``times``: reference solver only — explicit sample times instead of ``dt`` (repeated time = jump).
    ``linearised``: reference rocking only — Housner's linearised equation.
    ``history``: reference only — keep the time history in ``result.trace``.
    """
    if model not in ("rocking", "general"):
        raise AnalysisInputError(f"model must be 'rocking' or 'general', got {model!r}")
    if solver not in ("fast", "reference"):
        raise AnalysisInputError(f"solver must be 'fast' or 'reference', got {solver!r}")
    ax = check_record(acc_h, "acc_h") * G
    ay = np.zeros_like(ax) if acc_v is None else check_record(acc_v, "acc_v") * G
    if ay.shape != ax.shape:
        raise AnalysisInputError(f"acc_v has {ay.size} samples, acc_h has {ax.size}: they must match")
    check_angle(body, beta)
    e = resolve_restitutions(body, restitution)
    fall_plus, fall_minus = fall_angles(body, beta, criterion)
    if not (friction > 0 and math.isfinite(friction)):
        raise AnalysisInputError(f"friction must be a finite coefficient > 0, got {friction}")
    if not (t_after >= 0 and math.isfinite(t_after)):
        raise AnalysisInputError(f"t_after must be a finite duration >= 0 s, got {t_after}")
    if linearised and not (solver == "reference" and model == "rocking"):
        raise AnalysisInputError("linearised=True is offered by the reference rocking solver only")

    if solver == "reference":
        if times is not None:
            t = np.asarray(times, dtype=float)
            if t.shape != ax.shape or np.any(np.diff(t) < 0) or not np.all(np.isfinite(t)):
                raise AnalysisInputError("times: expected finite, non-decreasing sample times, one per sample")
        else:
            dt = check_dt(dt)
            t = np.arange(ax.size + 1) * dt
            ax, ay = np.append(ax, 0.0), np.append(ay, 0.0)
        return _reference(body, model, t, ax, ay, beta, e, friction, t_after, fall_plus, fall_minus,
                          theta0, omega0, linearised, history)
    if times is not None:
        raise AnalysisInputError("times= is for the reference solver; the fast engine takes a uniform dt")
    dt = check_dt(dt)
    ax, ay = np.append(ax, 0.0), np.append(ay, 0.0)
    return _fast(body, model, ax, ay, dt, beta, e, friction, t_after, fall_plus, fall_minus,
                 theta0, omega0, substeps(body, dt, step), acc_v is not None)


def _status_name(code: int) -> str:
    return ("rest", "overturned", "undecided")[code]


def _fast(body: Body, model: str, ax: np.ndarray, ay: np.ndarray, dt: float, beta: float,
          e: tuple[float, float], friction: float, t_after: float, fall_plus: float, fall_minus: float,
          theta0: float, omega0: float, n_sub: int, has_vertical: bool) -> SimulationResult:
    from analysis.envelope import block_bounds

    env = block_bounds(ax, ay)
    if model == "rocking":
        from analysis.fast_rocking import simulate_rocking

        d, t_o, th_max, imp, t_end, status, _, pre = simulate_rocking(
            ax, ay, env, dt, body.alpha_plus, body.k_plus, body.alpha_minus, body.k_minus, beta, e[0], e[1], n_sub,
            t_after, fall_plus, fall_minus, theta0, omega0)
        slide = (0.0, 0.0, 0.0)
    else:
        from analysis.fast_general import simulate_general

        d, t_o, th_max, imp, t_end, status, _, pre, u_peak, u_end, t_slid = simulate_general(
            ax, ay, env, dt, body.alpha_plus, body.r_plus, body.alpha_minus, body.r_minus, body.i_g**2, beta, e[0],
            e[1], friction, n_sub, t_after, fall_plus, fall_minus, theta0, omega0, has_vertical)
        slide = (float(u_peak), float(u_end), float(t_slid))
    return SimulationResult(int(d), None if math.isnan(t_o) else float(t_o), float(th_max),
                            _status_name(status), float(t_end), int(imp), model, "fast", bool(pre), *slide)


def _reference(body: Body, model: str, t: np.ndarray, ax: np.ndarray, ay: np.ndarray, beta: float,
               e: tuple[float, float], friction: float, t_after: float, fall_plus: float, fall_minus: float,
               theta0: float, omega0: float, linearised: bool, history: bool) -> SimulationResult:
    if model == "rocking":
        from analysis.reference import simulate_rocking_reference

        out = simulate_rocking_reference(
            t, ax, ay, alpha=body.alpha_plus, k=body.k_plus, beta=beta, restitution=e[0],
            t_after=t_after, fall_plus=fall_plus, fall_minus=fall_minus, theta0=theta0, omega0=omega0,
            linearised=linearised, history=history, alpha_minus=body.alpha_minus, k_minus=body.k_minus,
            restitution_minus=e[1])
        slide = (0.0, 0.0, 0.0)
    else:
        from analysis.reference_general import simulate_general_reference

        out = simulate_general_reference(
            t, ax, ay, alpha=body.alpha_plus, r=body.r_plus, ig2=body.i_g**2, beta=beta, restitution=e[0],
            friction=friction, t_after=t_after, fall_plus=fall_plus, fall_minus=fall_minus,
            theta0=theta0, omega0=omega0, history=history, alpha_minus=body.alpha_minus, r_minus=body.r_minus,
            restitution_minus=e[1])
        slide = (out.trace.slide_peak, out.trace.slide_residual, out.trace.slide_time)
    return SimulationResult(out.direction, out.t_overturn, out.theta_max, out.status, out.t_end,
                            len(out.trace.impacts), model, "reference", False, *slide, trace=out.trace)
