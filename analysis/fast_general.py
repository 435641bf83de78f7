"""Fast engine, general model (Eqs. 3–10): compiled stage machine REST/SLIDE/ROCK/ROCKSLIDE/FLIGHT.

The specification is ``docs/general-model.md``; the stage equations are those of
:mod:`analysis.equations`. Structure, conventions and returns mirror :mod:`analysis.fast_rocking`.
What a scene does not need is skipped (docs/architecture.md §3):

* REST costs only the scan for the earliest of its exits — uplift ± (Eq. 1), slide (|gx| > μ gz)
  and lift-off (gz < 0) — all linear inside a sample interval (the input is piecewise linear), so
  found exactly; a record that never reaches any of them costs that one scan (the pre-screen);
* a stage is integrated only when entered: with a high μ and no vertical input a scene runs
  REST/ROCK only, ROCK paying for two cheap reaction checks (slip, lift-off) at step ends;
* ROCK is the rocking model's RK4 on (θ, ω) (``fast_rocking._rk4``) on the same grid of ``n_sub``
  steps per sample interval; ROCKSLIDE integrates (θ, ω, v) with RK4 on that grid, halving a step
  (step-doubling error estimate) where the slide is fast (near the Painlevé limit); SLIDE
  (v' linear in t) and FLIGHT (v', w' linear in t, ω constant) are integrated exactly;
* θ events (impact, overturn) are located on the step's cubic Hermite interpolant; the other events
  (slip margin, R_n = 0, v = 0, landing) by Illinois (regula falsi) iterations that re-integrate the
  step from its start to the trial time;
* chattering (corner impacts accumulating in finite time) is summed analytically once a return
  flight is shorter than a quarter step, and ends in rest.

Every loop is bounded; a transition that takes no time is counted, and a chain of them (contact
conditions inconsistent at a boundary, e.g. R_n < 0 while a free flight would penetrate) is broken
by holding the pivot for one step. A pivot whose sliding is inconsistent (Painlevé: the denominator
of Eq. 9 not positive, below ``DEN_MIN``) sticks (``jam``). The corrections to docs/general-model.md
(lift-off through the sliding pivot, the corner impact of a sliding pivot) are described there.

Inputs are in SI (m/s²); ``ax``/``ay`` carry one extra trailing zero sample, after which the input
is zero: the free motion is followed for ``t_after`` seconds more or until rest/overturn.

``simulate_general`` is a short dispatcher over one step function per stage (``_rest_step``, ``_slide_step``,
``_flight_step``, ``_rock_step``), all inlined; the comment above them says what state they pass on.
"""

from __future__ import annotations

import math

import numpy as np

from analysis import hermite
from analysis.compiled_index import njit
from analysis.envelope import BLOCK, block_slack, margin_bound
from analysis.equations import (
    plate_gravity,
    rocking_sliding_acceleration,
    sliding_acceleration,
)
from analysis.fast_rocking import (
    OVERTURNED,
    REST,
    UNDECIDED,
    _accel,
    _rk4,
    _rk4_cs,
    carry_psi,
    pass_limit,
    step_window,
)
from analysis.general_stages import (
    DEN_MIN,
    EXIT_NONE,
    FLAT,
    MAX_INSTANT,
    ST_FLIGHT,
    ST_REST,
    ST_ROCK,
    ST_ROCKSLIDE,
    ST_SLIDE,
    after_reaction,
    break_instant_chain,
    corner,
    corner_impact_velocity,
    enter_stage,
    flight_entry,
    friction_tips,
    geometry,
    landing_omega,
    lean_offset,
    leave_rest,
    rest_exit,
    rest_leave,
    rest_margins,
    rock_margin,
    rock_margin_cs,
    rs_denominator,
)

__all__ = ["OVERTURNED", "REST", "UNDECIDED", "simulate_general"]

RS_SPLITS = 24
"""ROCKSLIDE: how many times a step may be halved (fast slide near the Painlevé limit)."""
RS_TOL = 1e-9
"""ROCKSLIDE: local error accepted per step (θ, ω·H, v·H/r) [rad], about that of a rocking step at
p·h = 0.05."""
ILLINOIS_ITER = 40


# --------------------------------------------------------------------------------------------------
# REST


@njit(cache=True, inline="always")
def _block_quiet(b: np.ndarray, cb: float, sb: float, ca_p: float, sa_p: float, ca_m: float, sa_m: float, mu: float,
                 has_vertical: bool) -> bool:
    """No sample of the block ``b`` (its extremes of a_x, a_y) has a REST margin above zero
    (``general_stages.rest_margins``: m = u g_x + w g_z for each (u, w) below)."""
    y_max, y_min = (b[2], b[3]) if has_vertical else (0.0, 0.0)
    lim = block_slack(b[0], b[1], y_max, y_min)
    return (margin_bound(ca_p, -sa_p, cb, sb, b[0], b[1], y_max, y_min) < lim
            and margin_bound(-ca_m, -sa_m, cb, sb, b[0], b[1], y_max, y_min) < lim
            and margin_bound(1.0, -mu, cb, sb, b[0], b[1], y_max, y_min) < lim
            and margin_bound(-1.0, -mu, cb, sb, b[0], b[1], y_max, y_min) < lim
            and margin_bound(0.0, -1.0, cb, sb, b[0], b[1], y_max, y_min) < lim)


@njit(cache=True)
def _next_exit(ax: np.ndarray, ay: np.ndarray, env: np.ndarray, dt: float, t: float, cb: float, sb: float,
               alpha_p: float, alpha_m: float, mu: float, has_vertical: bool) -> tuple[float, int]:
    """Earliest time ≥ t at which the resting block leaves rest, and how (EXIT_*); (inf, 0) if never.

    The margins (uplift ±, slide ±, lift-off) are linear in t inside a sample interval; after the
    record the input is zero and they are constant. The scan reads the samples; the interval where a
    margin turns positive is resolved by :func:`analysis.general_stages.rest_leave` (the tie rule) on
    the line the integration uses there (``fast_rocking.step_window``). Blocks of samples (``env``, the
    record's ``envelope.block_bounds``) where none of the five margins can turn positive are jumped.
    """
    n = ax.shape[0]
    ca_p, sa_p, ca_m, sa_m = math.cos(alpha_p), math.sin(alpha_p), math.cos(alpha_m), math.sin(alpha_m)
    tips_p, tips_m = friction_tips(mu, math.tan(alpha_p)), friction_tips(mu, math.tan(alpha_m))
    i = int(t / dt)
    if i < n - 1 and (i + 1) * dt <= t + 1e-12 * dt:  # as step_window: the next interval's line
        i += 1
    if i >= n - 1:
        m1, m2, m3, m4, m5 = rest_margins(0.0, 0.0, cb, sb, ca_p, sa_p, ca_m, sa_m, mu)
        kind = rest_exit(m1, m2, m3, m4, m5, tips_p, tips_m)
        return (t, kind) if kind != EXIT_NONE else (math.inf, EXIT_NONE)
    t0 = t
    while i < n - 1:
        j = i + 1
        if t0 != t and j % BLOCK == 0 and j + BLOCK <= n and _block_quiet(env[j // BLOCK], cb, sb, ca_p, sa_p, ca_m,
                                                                         sa_m, mu, has_vertical):
            i = j + BLOCK - 1
            t0 = i * dt
            continue
        a1y = ay[i + 1] if has_vertical else 0.0
        b1, b2, b3, b4, b5 = rest_margins(ax[i + 1], a1y, cb, sb, ca_p, sa_p, ca_m, sa_m, mu)
        if t0 == t or rest_exit(b1, b2, b3, b4, b5, tips_p, tips_m) != EXIT_NONE:
            sx = (ax[i + 1] - ax[i]) / dt
            a0y, sy = (ay[i], (a1y - ay[i]) / dt) if has_vertical else (0.0, 0.0)
            t_x, kind = rest_leave(t0, (i + 1) * dt, i * dt, ax[i], sx, a0y, sy, ax[i + 1], a1y, cb, sb, ca_p,
                                   sa_p, ca_m, sa_m, mu, tips_p, tips_m)
            if kind != EXIT_NONE:
                return t_x, kind
        i += 1
        t0 = i * dt
    return math.inf, EXIT_NONE


# --------------------------------------------------------------------------------------------------
# ROCK (pivot sticks): reactions and their events


@njit(cache=True)
def _rock_f(tau: float, which: int, theta: float, omega: float, t: float, ti: float, a0x: float, sx: float,
            a0y: float, sy: float, s: float, alpha: float, r: float, k: float, mu: float, cb: float, sb: float
            ) -> tuple[float, float, float, float, float]:
    """Event function of ROCK at step fraction τ (re-integrated): which 0 → |R_t| − μ R_n, 1 → −R_n.
    Returns (f, θ, ω, R_t, R_n)."""
    if tau > 0.0:
        th, om = _rk4(theta, omega, t, tau, ti, a0x, sx, a0y, sy, s, alpha, k, cb, sb)
    else:
        th, om = theta, omega
    tt = t + tau
    gx, gz = plate_gravity(a0x + sx * (tt - ti), a0y + sy * (tt - ti), cb, sb)
    f, rt, rn = rock_margin(th, om, s, gx, gz, alpha, r, k, mu)
    if which == 1:
        f = -rn
    return f, th, om, rt, rn


@njit(cache=True)
def _locate_rock(which: int, hi: float, f_hi: float, theta: float, omega: float, t: float, ti: float,
                 a0x: float, sx: float, a0y: float, sy: float, s: float, alpha: float, r: float, k: float,
                 mu: float, cb: float, sb: float, H: float) -> float:
    """Illinois on the ROCK event function in (0, hi]: the first τ where it is > 0 (hi side)."""
    f_lo, _, _, _, _ = _rock_f(0.0, which, theta, omega, t, ti, a0x, sx, a0y, sy, s, alpha, r, k, mu, cb, sb)
    if f_lo > 0.0:
        return 0.0
    lo = 0.0
    side = 0
    for _ in range(ILLINOIS_ITER):
        if hi - lo <= 1e-12 * H:
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        fx, _, _, _, _ = _rock_f(x, which, theta, omega, t, ti, a0x, sx, a0y, sy, s, alpha, r, k, mu, cb, sb)
        if fx > 0.0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
    return hi


# --------------------------------------------------------------------------------------------------
# ROCKSLIDE


@njit(cache=True, inline="always")
def _rs_deriv(theta: float, omega: float, t: float, ti: float, a0x: float, sx: float, a0y: float, sy: float,
              s: float, slip: float, alpha: float, r: float, ig2: float, mu: float, cb: float, sb: float
              ) -> tuple[float, float]:
    gx, gz = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
    th_dd, x_dd, _ = rocking_sliding_acceleration(theta, omega, s, slip, gx, gz, alpha, r, ig2, mu)
    return th_dd, x_dd


@njit(cache=True)
def _rk4_rs(theta: float, omega: float, v: float, t: float, H: float, ti: float, a0x: float, sx: float,
            a0y: float, sy: float, s: float, slip: float, alpha: float, r: float, ig2: float, mu: float,
            cb: float, sb: float) -> tuple[float, float, float]:
    a1, x1 = _rs_deriv(theta, omega, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    om2 = omega + 0.5 * H * a1
    a2, x2 = _rs_deriv(theta + 0.5 * H * omega, om2, t + 0.5 * H, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                       ig2, mu, cb, sb)
    om3 = omega + 0.5 * H * a2
    a3, x3 = _rs_deriv(theta + 0.5 * H * om2, om3, t + 0.5 * H, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                       ig2, mu, cb, sb)
    om4 = omega + H * a3
    a4, x4 = _rs_deriv(theta + H * om3, om4, t + H, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    theta1 = theta + H / 6.0 * (omega + 2.0 * om2 + 2.0 * om3 + om4)
    omega1 = omega + H / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    v1 = v + H / 6.0 * (x1 + 2.0 * x2 + 2.0 * x3 + x4)
    return theta1, omega1, v1


@njit(cache=True)
def _rs_f(tau: float, which: int, theta: float, omega: float, v: float, t: float, ti: float, a0x: float,
          sx: float, a0y: float, sy: float, s: float, slip: float, alpha: float, r: float, ig2: float,
          mu: float, cb: float, sb: float) -> tuple[float, float, float, float]:
    """Event function of ROCKSLIDE at τ: which 0 → −slip·v (the slide stops), 1 → −R_n (lift-off).
    Returns (f, θ, ω, v)."""
    if tau > 0.0:
        th, om, vv = _rk4_rs(theta, omega, v, t, tau, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    else:
        th, om, vv = theta, omega, v
    if which == 0:
        return -slip * vv, th, om, vv
    tt = t + tau
    gx, gz = plate_gravity(a0x + sx * (tt - ti), a0y + sy * (tt - ti), cb, sb)
    _, _, rn = rocking_sliding_acceleration(th, om, s, slip, gx, gz, alpha, r, ig2, mu)
    return -rn, th, om, vv


@njit(cache=True)
def _locate_rs(which: int, hi: float, f_hi: float, theta: float, omega: float, v: float, t: float, ti: float,
               a0x: float, sx: float, a0y: float, sy: float, s: float, slip: float, alpha: float, r: float,
               ig2: float, mu: float, cb: float, sb: float, H: float) -> float:
    """Illinois on a ROCKSLIDE event function in (0, hi]: the first τ where it is ≥ 0 (hi side)."""
    f_lo, _, _, _ = _rs_f(0.0, which, theta, omega, v, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu,
                          cb, sb)
    if f_lo > 0.0:
        return 0.0
    if f_hi <= 0.0:  # exactly zero at hi
        f_hi = 0.0
    lo = 0.0
    side = 0
    for _ in range(ILLINOIS_ITER):
        if hi - lo <= 1e-12 * H or f_hi == f_lo:
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        fx, _, _, _ = _rs_f(x, which, theta, omega, v, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu,
                            cb, sb)
        if fx >= 0.0 and (which == 0 or fx > 0.0):
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
    return hi


# --------------------------------------------------------------------------------------------------
# FLIGHT (exact: gx, gz linear in t inside a sample interval, ω constant)


@njit(cache=True, inline="always")
def _flight_state(tau: float, theta: float, omega: float, v: float, z: float, w: float, gx0: float,
                  gx1: float, gz0: float, gz1: float) -> tuple[float, float, float, float]:
    """(θ, v, z, w) after τ of free flight."""
    t2 = tau * tau
    return (theta + omega * tau, v + gx0 * tau + 0.5 * gx1 * t2,
            z + w * tau - 0.5 * gz0 * t2 - gz1 * t2 * tau / 6.0, w - gz0 * tau - 0.5 * gz1 * t2)


@njit(cache=True, inline="always")
def _gap(tau: float, theta: float, omega: float, v: float, z: float, w: float, gx0: float, gx1: float,
         gz0: float, gz1: float, alpha_p: float, r_p: float, alpha_m: float, r_m: float, psi_ref: float,
         r_ref: float) -> float:
    """Height of the lowest corner (sign θ) above the plate after τ of flight.

    In FLIGHT ``z`` is ζ = z − r_ref cos ψ_ref, the height of the centre of mass over its height at
    lift-off (ψ_ref = α − |θ| then, r_ref and α that lowest corner's), so that the gap ζ − r (cos ψ − cos ψ_ref)
    is free of cancellation right after lift-off (where it grows like τ²). Once θ has changed sign (an
    off-centre centre of mass: the other corner, r ≠ r_ref) it is ζ − (r cos ψ − r_ref cos ψ_ref)."""
    th, _, zz, _ = _flight_state(tau, theta, omega, v, z, w, gx0, gx1, gz0, gz1)
    alpha, r = (alpha_p, r_p) if th >= 0.0 else (alpha_m, r_m)
    psi = alpha - abs(th)
    if r == r_ref:
        return zz + 2.0 * r * math.sin(0.5 * (psi + psi_ref)) * math.sin(0.5 * (psi - psi_ref))
    return zz - (r * math.cos(psi) - r_ref * math.cos(psi_ref))


@njit(cache=True)
def _locate_landing(lo: float, hi: float, theta: float, omega: float, v: float, z: float, w: float,
                    gx0: float, gx1: float, gz0: float, gz1: float, alpha_p: float, r_p: float, alpha_m: float,
                    r_m: float, psi_ref: float, r_ref: float, H: float) -> float:
    """Illinois on the gap in (lo, hi], gap(lo) > 0 ≥ gap(hi): the landing time (hi side)."""
    f_lo = _gap(lo, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m, psi_ref, r_ref)
    f_hi = _gap(hi, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m, psi_ref, r_ref)
    side = 0
    for _ in range(ILLINOIS_ITER):
        if hi - lo <= 1e-12 * H or f_hi == f_lo:
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        fx = _gap(x, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m, psi_ref, r_ref)
        if fx <= 0.0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
    return hi


# --------------------------------------------------------------------------------------------------
# slide displacement u (docs/general-model.md, *Slide displacement*)


@njit(cache=True, inline="always")
def _flight_shift(tau: float, theta: float, omega: float, v: float, gx0: float, gx1: float, alpha_p: float,
                  r_p: float, alpha_m: float, r_m: float) -> float:
    """Change of u over τ of flight: the centre of mass's (v' = gx0 + gx1 τ) plus the lean offset's."""
    return (v * tau + (0.5 * gx0 + gx1 * tau / 6.0) * tau * tau
            + lean_offset(theta + omega * tau, alpha_p, r_p, alpha_m, r_m)
            - lean_offset(theta, alpha_p, r_p, alpha_m, r_m))


@njit(cache=True)
def _rs_shift(theta: float, omega: float, v: float, theta1: float, omega1: float, v1: float, t: float, H: float,
              ti: float, a0x: float, sx: float, a0y: float, sy: float, s: float, slip: float, alpha: float,
              r: float, ig2: float, mu: float, cb: float, sb: float) -> float:
    """∫ v dt over a ROCKSLIDE step of length H from its two ends (cubic Hermite quadrature, the order of
    the RK4 step): the sliding pivot's displacement."""
    if H <= 0.0:
        return 0.0
    _, x0 = _rs_deriv(theta, omega, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    _, x1 = _rs_deriv(theta1, omega1, t + H, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    return 0.5 * H * (v + v1) + H * H * (x0 - x1) / 12.0


# --------------------------------------------------------------------------------------------------
# SLIDE (exact: v' = gx − μ slip gz is linear in t inside a sample interval)


@njit(cache=True)
def _first_root(c0: float, c1: float, c2: float, H: float) -> float:
    """Smallest τ in (0, H] where c0 + c1 τ + c2 τ² (≥ 0 at τ = 0, not starting downwards) falls to 0;
    inf if none. A start at 0 going downwards gives 0."""
    if c0 <= 0.0 and (c1 < 0.0 or (c1 == 0.0 and c2 < 0.0)):
        return 0.0
    if c2 == 0.0:
        if c1 < 0.0:
            tau = -c0 / c1
            return tau if tau <= H else math.inf
        return math.inf
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return math.inf
    sq = math.sqrt(disc)
    q = -0.5 * (c1 + (sq if c1 >= 0.0 else -sq))
    best = math.inf
    for tau in (q / c2, c0 / q if q != 0.0 else math.inf):
        if 0.0 < tau <= H and tau < best:
            best = tau
    return best


# --------------------------------------------------------------------------------------------------
# The stage machine: simulate_general dispatches each step to its stage's step function.
#
# A scene's state travels between them in tuples, each returned whole by the function that changes it:
#   motion  (t, θ, ω, v, z, w): time [s]; the tilt θ [rad] and ω [rad/s], positive towards +x; v [m/s] along
#           +x: the base's (SLIDE), the sliding pivot's (ROCKSLIDE) or the centre of mass's (FLIGHT); in
#           FLIGHT z [m] the centre of mass's height over its height at lift-off and w [m/s] its rate (_gap)
#   contact (stage, s, slip, ψ_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest): the stage; the
#           pivot's side s and the slide's direction slip (±1); the lift-off corner's ψ_ref [rad] and r_ref [m]
#           (_gap); fresh: the stage was just entered (its entry conditions are checked); jam: ROCK's pivot
#           sticks although |R_t| > μ R_n (sliding inconsistent); hold: no reaction checks for one step (breaks
#           a chain of instant transitions); instant: transitions in a row that took no time, t_last [s] the
#           last transition's time; t_rest [s] when the body last came to rest
#   tally   (θ_max, u, u_peak, t_slide, impacts, steps): the largest |θ| [rad]; the slide displacement u [m]
#           and its largest |u| [m]; the time the base or the pivot slid [s]; corner impacts and landings; steps
#   trig    (θ, s, cos ψ, sin ψ): ROCK's cos/sin of ψ, carried from step to step as in the rocking kernel
# and the step's input in ``seg`` (t_i, ax(t_i), its slope, ay(t_i), its slope) [s, m/s², m/s³]: the sample
# interval the step lies in; ``sides`` (α, R, k, e) of the +x corner, then of the −x corner.


@njit(cache=True, inline="always")
def _outcome(direction: int, t_overturn: float, t_end: float, status: int, prescreen: bool, tally: tuple
             ) -> tuple[int, float, float, int, float, int, int, bool, float, float, float]:
    """simulate_general's return from the scene's tally."""
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    return direction, t_overturn, theta_max, impacts, t_end, status, steps, prescreen, u_peak, u, t_slide


@njit(cache=True, inline="always")
def _rest_step(ax: np.ndarray, ay: np.ndarray, env: np.ndarray, dt: float, cb: float, sb: float, alpha_p: float,
               r_p: float, ca_p: float, alpha_m: float, mu: float, has_vertical: bool, motion: tuple,
               contact: tuple) -> tuple[bool, tuple, tuple]:
    """REST: scan the input for the earliest exit (``_next_exit``) and leave rest there. Returns (settled: no
    exit before the record's end, motion, contact)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    t_x, kind = _next_exit(ax, ay, env, dt, t, cb, sb, alpha_p, alpha_m, mu, has_vertical)
    settled = kind == EXIT_NONE
    if not settled:
        t = t_x
        theta = omega = v = w = 0.0
        jam = False
        stage, s, slip, z = leave_rest(kind, s, slip, z, r_p, ca_p)
        fresh = True
        if t == t_last:
            instant += 1
        t_last = t
    return (settled, (t, theta, omega, v, z, w),
            (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest))


@njit(cache=True, inline="always")
def _enter(motion: tuple, contact: tuple, t_stop: float, h: float, gx0: float, gz0: float, geo: tuple, ig2: float,
           mu: float) -> tuple[bool, tuple, tuple]:
    """The transitions that take no time at a step's start: a chain of more than ``MAX_INSTANT`` of them is
    broken (the pivot held for one step, or one step of rest), then a stage just entered checks its entry
    conditions (``enter_stage``). Returns (go: the stage integrates this step, motion, contact)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    go = True
    if fresh and instant > MAX_INSTANT:
        instant = 0
        stage, s = break_instant_chain(stage, theta, omega, v, s)
        if stage == ST_ROCK:
            hold, fresh, v = True, False, 0.0
        elif stage == ST_REST:  # it rests for one step before its next exit
            theta = omega = v = w = 0.0
            t_rest = t
            t = min(t + h, t_stop)
            go = False
    if go and fresh:
        fresh = False
        new, theta, omega, v, w, z, s, slip, hold, jam, psi_ref, r_ref = enter_stage(
            stage, hold, jam, theta, omega, v, w, z, s, slip, psi_ref, r_ref, gx0, gz0, geo, ig2, mu)
        if new != stage:
            stage = new
            fresh = True
            if t == t_last:
                instant += 1
            t_last = t
            if stage == ST_REST:
                t_rest = t
            go = False
    return (go, (t, theta, omega, v, z, w),
            (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest))


@njit(cache=True, inline="always")
def _slide_step(motion: tuple, contact: tuple, tally: tuple, t_b: float, t_stop: float, sx: float, sy: float,
                gx0: float, gz0: float, cb: float, sb: float, mu: float, r_p: float, ca_p: float
                ) -> tuple[tuple, tuple, tuple]:
    """SLIDE to the sample interval's end ``t_b`` [s], exact (v' = gx − μ slip gz is linear in t): one step per
    sample interval, cut where the slide stops (REST) or the base lifts off (gz = 0: FLIGHT)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    te_s = min(t_b, t_stop)
    Hs = te_s - t
    gx1, gz1 = -sx * cb + sy * sb, sx * sb + sy * cb
    a0 = sliding_acceleration(slip, gx0, gz0, mu)
    a1 = gx1 - mu * slip * gz1
    c1 = slip * a0
    if v == 0.0 and c1 < 0.0:
        c1 = 0.0
    tau_v = _first_root(slip * v, c1, 0.5 * slip * a1, Hs)
    tau_z = -gz0 / gz1 if gz1 < 0.0 else math.inf
    if not (0.0 <= tau_z <= Hs):
        tau_z = math.inf
    steps += 1
    if tau_v == math.inf and tau_z == math.inf:
        u += v * Hs + (0.5 * a0 + a1 * Hs / 6.0) * Hs * Hs
        u_peak, t_slide = max(u_peak, abs(u)), t_slide + Hs
        v += a0 * Hs + 0.5 * a1 * Hs * Hs
        t = te_s
        instant = 0
    else:
        tau_s = min(tau_v, tau_z)
        u += v * tau_s + (0.5 * a0 + a1 * tau_s / 6.0) * tau_s * tau_s
        u_peak, t_slide = max(u_peak, abs(u)), t_slide + tau_s
        if tau_v <= tau_z:
            t += tau_v
            v = 0.0
            stage, t_rest = ST_REST, t
        else:
            v += a0 * tau_z + 0.5 * a1 * tau_z * tau_z
            t += tau_z
            stage, theta, omega, w, z = ST_FLIGHT, 0.0, 0.0, 0.0, r_p * ca_p
        fresh = True
        if t == t_last:
            instant += 1
        t_last = t
    return ((t, theta, omega, v, z, w), (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps))


@njit(cache=True, inline="always")
def _flight_step(motion: tuple, contact: tuple, tally: tuple, H: float, sx: float, sy: float, gx0: float,
                 gz0: float, cb: float, sb: float, geo: tuple, ig2: float, fall_plus: float, fall_minus: float
                 ) -> tuple[int, tuple, tuple, tuple]:
    """FLIGHT over a step of H [s], exact (v', w' linear in t, ω constant), cut at an overturn in the air or
    a landing (located by Illinois on the gap, ``_locate_landing``). Returns (direction of an overturn, else
    0; motion, contact, tally): on an overturn t is its time and θ_max at least the fall angle."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    alpha_p, r_p, alpha_m, r_m = geo[0], geo[1], geo[5], geo[6]
    d = 0
    was_fresh = t == t_last
    gx1, gz1 = -sx * cb + sy * sb, sx * sb + sy * cb
    th1, v1, z1, w1 = _flight_state(H, theta, omega, v, z, w, gx0, gx1, gz0, gz1)
    steps += 1
    tau = H
    event = 0
    # overturn in the air (θ linear)
    if th1 >= fall_plus and omega > 0.0:
        tau, event = (fall_plus - theta) / omega, 1
    elif -th1 >= fall_minus and omega < 0.0:
        tau, event = (-fall_minus - theta) / omega, 1
    g1 = _gap(tau, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m, psi_ref, r_ref)
    if g1 <= 0.0:
        g0 = _gap(0.0, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m, psi_ref, r_ref)
        lo = -1.0
        if g0 > 0.0 and not was_fresh:
            lo = 0.0
        else:  # just lifted off (gap 0): find the hop, if any
            frac = 0.5  # of the step tried
            for _ in range(40):
                if _gap(frac * tau, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m, r_m,
                        psi_ref, r_ref) > 0.0:
                    lo = frac * tau
                    break
                frac *= 0.5
        if lo < 0.0:
            tau_l = 0.0
        else:
            tau_l = _locate_landing(lo, tau, theta, omega, v, z, w, gx0, gx1, gz0, gz1, alpha_p, r_p, alpha_m,
                                    r_m, psi_ref, r_ref, H)
        tau, event = tau_l, 2
    th1, v1, z1, w1 = _flight_state(tau, theta, omega, v, z, w, gx0, gx1, gz0, gz1)
    theta_max = max(theta_max, abs(th1))
    if event == 1:
        d = 1 if omega > 0.0 else -1
        fall = fall_plus if d > 0 else fall_minus
        u += _flight_shift(tau, theta, omega, v, gx0, gx1, alpha_p, r_p, alpha_m, r_m)
        u_peak = max(u_peak, abs(u))
        t += tau
        theta_max = max(theta_max, fall)
    else:
        if tau > 0.0:
            instant = 0
        u += _flight_shift(tau, theta, omega, v, gx0, gx1, alpha_p, r_p, alpha_m, r_m)
        u_peak = max(u_peak, abs(u))
        t += tau
        theta, v, z, w = th1, v1, z1, w1
        if event == 2:
            impacts += 1
            if abs(theta) < FLAT:
                theta = omega = w = 0.0
                if v == 0.0:
                    stage, t_rest = ST_REST, t
                else:
                    stage, slip = ST_SLIDE, (1.0 if v > 0.0 else -1.0)
            else:
                s = 1.0 if theta > 0.0 else -1.0
                alpha, r, _, _, _ = corner(geo, s)
                omega = landing_omega(theta, omega, v, w, alpha, r, ig2)
                stage, v, jam = ST_ROCK, 0.0, False
            fresh = True
            if t == t_last:
                instant += 1
            t_last = t
    return (d, (t, theta, omega, v, z, w),
            (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps))


@njit(cache=True, inline="always")
def _after_impact(omega: float, vp: float, e: float, s: float, slip: float) -> tuple[int, float, float, float, float]:
    """The stage after a corner impact with ω = e ω⁻ [rad/s] after it and the new pivot's slide velocity vp
    [m/s]: (stage, ω, v, slip, s). Rocking ends (e = 0 or |ω| < 1e-12) in REST or SLIDE, else it goes on
    about the other corner (s flips) in ROCK or ROCKSLIDE."""
    if e == 0.0 or abs(omega) < 1e-12:
        if vp == 0.0:
            return ST_REST, 0.0, 0.0, slip, s
        return ST_SLIDE, 0.0, vp, (1.0 if vp > 0.0 else -1.0), s
    if vp == 0.0:
        return ST_ROCK, omega, 0.0, slip, -s
    return ST_ROCKSLIDE, omega, vp, (1.0 if vp > 0.0 else -1.0), -s


@njit(cache=True, inline="always")
def _short_return(motion: tuple, contact: tuple, tally: tuple, rs: bool, alpha: float, r: float, k: float, e: float,
                  seg: tuple, H: float, ig2: float, mu: float, cb: float, sb: float
                  ) -> tuple[bool, tuple, tuple, tuple]:
    """Chattering: at θ = 0 after an impact, a return flight shorter than a quarter step is summed
    analytically (a sliding pivot only when its slide does not stop within the flight: that is integrated).
    Returns (taken, motion, contact, tally)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    ti, a0x, sx, a0y, sy = seg
    if rs:
        acc0, xdd0 = _rs_deriv(0.0, omega, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
    else:
        acc0 = _accel(0.0, t, ti, a0x, sx, a0y, sy, s, alpha, k, cb, sb)
        xdd0 = 0.0
    taken = False
    if s * acc0 < 0.0 and 2.0 * abs(omega) / abs(acc0) < 0.25 * H and \
            (not rs or abs(v) > 4.0 * abs(xdd0) * abs(omega) / abs(acc0)):
        taken = True
        dtc = 2.0 * abs(omega) / abs(acc0)
        t += dtc
        impacts += 1
        hold = False
        jam = False
        vp = 0.0
        if rs:
            u += v * dtc + 0.5 * xdd0 * dtc * dtc
            u_peak, t_slide = max(u_peak, abs(u)), t_slide + dtc
            v1 = v + xdd0 * dtc
            v1 = v1 if v1 * v > 0.0 else 0.0
            vp = corner_impact_velocity(v1, -omega, e, r, alpha)
        stage, omega, v, slip, s = _after_impact(-e * omega, vp, e, s, slip)
        if stage == ST_REST:
            t_rest = t
        if stage in (ST_REST, ST_SLIDE):  # rocking ended
            fresh = True
        instant = 0
        t_last = t
    return (taken, (t, theta, omega, v, z, w),
            (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps))


@njit(cache=True, inline="always")
def _rs_step(theta: float, omega: float, v: float, t: float, H: float, seg: tuple, s: float, slip: float,
             alpha: float, r: float, ig2: float, mu: float, cb: float, sb: float
             ) -> tuple[bool, float, float, float, float]:
    """ROCKSLIDE's RK4 step with error control by step doubling: near the Painlevé limit (small denominator of
    Eq. 9) the slide runs on a much shorter time scale than rocking; the step of H [s] is halved (at most
    ``RS_SPLITS`` times) until one step and two half steps agree to ``RS_TOL`` (θ, ω·H, v·H/r) [rad] with the
    denominator above ``DEN_MIN``. Returns (ok, θ, ω, v, H) at the end of the step taken; not ok: Painlevé
    ahead."""
    ti, a0x, sx, a0y, sy = seg
    theta1, omega1, v1 = theta, omega, v
    for _ in range(RS_SPLITS):
        theta1, omega1, v1 = _rk4_rs(theta, omega, v, t, H, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu, cb, sb)
        th_h, om_h, v_h = _rk4_rs(theta, omega, v, t, 0.5 * H, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu,
                                  cb, sb)
        th_h, om_h, v_h = _rk4_rs(th_h, om_h, v_h, t + 0.5 * H, 0.5 * H, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                                  ig2, mu, cb, sb)
        err = max(abs(th_h - theta1), abs(om_h - omega1) * H, abs(v_h - v1) * H / r) / 15.0
        if math.isfinite(err) and err <= RS_TOL and \
                rs_denominator(th_h, s, slip, alpha, r, ig2, mu) > DEN_MIN * (ig2 + r * r):
            return True, th_h, om_h, v_h, H
        H *= 0.5
    return False, theta1, omega1, v1, H


@njit(cache=True, inline="always")
def _reaction_event(rs: bool, hold: bool, jam: bool, ev: int, tau_ev: float, th_e: float, om_e: float, v_e: float,
                    c_e: float, s_e: float, theta: float, omega: float, v: float, t: float, H: float, seg: tuple,
                    s: float, slip: float, alpha: float, r: float, k: float, ig2: float, mu: float, cb: float,
                    sb: float) -> tuple[float, int, bool]:
    """ROCK's and ROCKSLIDE's reaction and slide events before the θ event or the step's end τ_ev [s] (checked
    there, located by Illinois): (τ [s] from the step's start, inf if none; kind: −1 none, 0 the slide stops,
    1 the sliding pivot lifts off (R_n = 0), 2 ROCK's pivot slips or lifts off; jam). ``c_e``, ``s_e``: cos/sin
    of ψ at the step's end, read in ROCK without a θ event."""
    ti, a0x, sx, a0y, sy = seg
    tt = t + tau_ev
    gxe, gze = plate_gravity(a0x + sx * (tt - ti), a0y + sy * (tt - ti), cb, sb)
    tau_r = math.inf
    kind_r = -1
    if rs:
        _, _, rn_e = rocking_sliding_acceleration(th_e, om_e, s, slip, gxe, gze, alpha, r, ig2, mu)
        if slip * v_e <= 0.0:
            tau_r = _locate_rs(0, tau_ev, -slip * v_e, theta, omega, v, t, ti, a0x, sx, a0y, sy, s, slip,
                               alpha, r, ig2, mu, cb, sb, H)
            kind_r = 0
        if rn_e < 0.0:
            tau_n = _locate_rs(1, tau_ev, -rn_e, theta, omega, v, t, ti, a0x, sx, a0y, sy, s, slip, alpha,
                               r, ig2, mu, cb, sb, H)
            if tau_n < tau_r:
                tau_r, kind_r = tau_n, 1
    elif not hold:
        if ev == 0:
            f_e, _, rn_e = rock_margin_cs(om_e, s, gxe, gze, c_e, s_e, r, k, mu)
        else:
            f_e, _, rn_e = rock_margin(th_e, om_e, s, gxe, gze, alpha, r, k, mu)
        which = 0
        if jam:
            if f_e <= 0.0:
                jam = False
            else:
                f_e, which = -rn_e, 1
        if f_e > 0.0:
            tau_r = _locate_rock(which, tau_ev, f_e, theta, omega, t, ti, a0x, sx, a0y, sy, s, alpha, r, k,
                                 mu, cb, sb, H)
            kind_r = 2
    return tau_r, kind_r, jam


@njit(cache=True, inline="always")
def _at_reaction(motion: tuple, contact: tuple, tally: tuple, rs: bool, kind_r: int, tau_r: float, u_top: float,
                 hc: tuple, H: float, seg: tuple, alpha: float, r: float, k: float, ig2: float, mu: float, cb: float,
                 sb: float) -> tuple[tuple, tuple, tuple]:
    """ROCK's or ROCKSLIDE's step of H [s] cut at its reaction event τ_r [s] (``_reaction_event``'s kind_r):
    θ_max over the part taken (``hc``: the step's Hermite coefficients, ``u_top`` where |θ| peaks in it or −1
    if not found yet), the slide, then what the pivot does: FLIGHT on a lift-off of the sliding pivot, else
    ``after_reaction`` (stick, slide the other way, fly)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    ti, a0x, sx, a0y, sy = seg
    c3, c2, c1h, c0 = hc
    if rs:
        _, th_r, om_r, v_r = _rs_f(tau_r, 0, theta, omega, v, t, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                                   ig2, mu, cb, sb)
    else:
        _, th_r, om_r, _, _ = _rock_f(tau_r, 0, theta, omega, t, ti, a0x, sx, a0y, sy, s, alpha, r, k,
                                      mu, cb, sb)
        v_r = 0.0
    if u_top < 0.0:
        u_top = hermite.argmax_scaled(c3, c2, c1h, c0, s)
    if u_top * H <= tau_r:
        theta_max = max(theta_max, abs(hermite.value(c3, c2, c1h, c0, u_top)))
    theta_max = max(theta_max, abs(th_r))
    if tau_r > 0.0:
        instant = 0
    if rs:
        u += _rs_shift(theta, omega, v, th_r, om_r, v_r, t, tau_r, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                       ig2, mu, cb, sb)
        u_peak, t_slide = max(u_peak, abs(u)), t_slide + tau_r
    t += tau_r
    theta, omega = th_r, om_r
    gxr, gzr = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
    if kind_r == 1:  # lift-off of the sliding pivot
        z, v, w = flight_entry(theta, omega, v_r, s, alpha, r)
        stage = ST_FLIGHT
    else:  # ROCK's reactions, or the slide stops: stick, slide (the other way) or fly
        stage, v, w, z, slip, jam, hold = after_reaction(theta, omega, v_r, w, z, s, slip, jam, kind_r == 0,
                                                         gxr, gzr, alpha, r, ig2, k, mu)
    fresh = not hold
    if t == t_last:
        instant += 1
    t_last = t
    return ((t, theta, omega, v, z, w), (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps))


@njit(cache=True, inline="always")
def _at_theta_event(motion: tuple, contact: tuple, tally: tuple, rs: bool, ev: int, tau_ev: float, th_e: float,
                    om_e: float, v_e: float, u_top: float, hc: tuple, fall: float, seg: tuple, alpha: float,
                    r: float, e: float, ig2: float, mu: float, cb: float, sb: float) -> tuple[int, tuple, tuple, tuple]:
    """ROCK's or ROCKSLIDE's step cut at its θ event τ_ev [s], where the state is (θ_e, ω_e, v_e): ev 1 the
    body overturns (returns its direction; t its time, θ_max the fall angle), ev 2 a corner impact (the stage
    after it: ``_after_impact``; returns 0)."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    ti, a0x, sx, a0y, sy = seg
    c3, c2, c1h, c0 = hc
    d = 0
    if rs:
        u += _rs_shift(theta, omega, v, th_e, om_e, v_e, t, tau_ev, ti, a0x, sx, a0y, sy, s, slip, alpha,
                       r, ig2, mu, cb, sb)
        u_peak, t_slide = max(u_peak, abs(u)), t_slide + tau_ev
    t += tau_ev
    if ev == 1:  # overturned
        d = int(s)
        theta_max = fall
    else:  # impact
        theta_max = max(theta_max, abs(hermite.value(c3, c2, c1h, c0, u_top)))
        impacts += 1
        vp = corner_impact_velocity(v_e, om_e, e, r, alpha) if rs else 0.0
        theta = 0.0
        if tau_ev > 0.0:
            instant = 0
        stage, omega, v, slip, s = _after_impact(e * om_e, vp, e, s, slip)
        if stage == ST_REST:
            t_rest = t
        elif stage in (ST_ROCK, ST_ROCKSLIDE):  # rocking goes on about the other corner
            jam = False
        fresh = True
        if t == t_last:
            instant += 1
        t_last = t
    return (d, (t, theta, omega, v, z, w),
            (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps))


@njit(cache=True, inline="always")
def _rock_step(motion: tuple, contact: tuple, tally: tuple, trig: tuple, seg: tuple, H: float, te: float,
               sides: tuple, ig2: float, mu: float, cb: float, sb: float, fall_plus: float, fall_minus: float
               ) -> tuple[int, tuple, tuple, tuple, tuple]:
    """ROCK (the rocking model's RK4 on (θ, ω), ``fast_rocking._rk4``) or ROCKSLIDE (RK4 on (θ, ω, v),
    ``_rs_step``) over a step of H [s] ending at ``te`` [s]; θ events (overturn, impact) on the step's cubic
    Hermite interpolant, then the reaction events before them (``_reaction_event``). Returns (direction of an
    overturn, else 0; motion, contact, tally, trig): on an overturn t is its time and θ_max the fall angle."""
    t, theta, omega, v, z, w = motion
    stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest = contact
    theta_max, u, u_peak, t_slide, impacts, steps = tally
    trig_theta, trig_s, c_psi, s_psi = trig
    ti, a0x, sx, a0y, sy = seg
    rs = stage == ST_ROCKSLIDE
    # the pivot's corner (the body's sides differ when its centre of mass is off the middle)
    if s > 0.0:
        alpha, r, k, e = sides[0], sides[1], sides[2], sides[3]
    else:
        alpha, r, k, e = sides[4], sides[5], sides[6], sides[7]
    if theta == 0.0 and omega != 0.0:
        taken, motion_c, contact_c, tally_c = _short_return(motion, contact, tally, rs, alpha, r, k, e, seg, H, ig2,
                                                            mu, cb, sb)
        if taken:
            return 0, motion_c, contact_c, tally_c, trig
    if rs:
        ok, theta1, omega1, v1, H = _rs_step(theta, omega, v, t, H, seg, s, slip, alpha, r, ig2, mu, cb, sb)
        te = t + H
        if not ok:  # Painlevé ahead: the pivot sticks
            stage, v, jam, fresh = ST_ROCK, 0.0, True, False
            return (0, (t, theta, omega, v, z, w),
                    (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest), tally, trig)
    else:
        if theta != trig_theta or s != trig_s:
            c_psi, s_psi = math.cos(alpha - s * theta), math.sin(alpha - s * theta)
        theta1, omega1 = _rk4_cs(theta, omega, c_psi, s_psi, t, H, ti, a0x, sx, a0y, sy, s, k, cb, sb)
        v1 = 0.0
    steps += 1
    fall = fall_plus if s > 0.0 else fall_minus
    # θ events on the Hermite interpolant: 1 overturn, 2 impact
    ev = 0
    tau_ev = H
    c3, c2, c1h, c0 = hermite.coefficients(theta, omega, theta1, omega1, H)
    u_top = -1.0  # where |θ| peaks in the step: found only where it is read (impact, reaction event, turn)
    if s * theta1 >= fall:
        tau_ev, ev = hermite.crossing(c3, c2, c1h, c0, s, fall, 0.0) * H, 1
    elif s * theta1 < 0.0 or (theta1 == 0.0 and s * omega1 < 0.0):
        u_top = hermite.argmax_scaled(c3, c2, c1h, c0, s)
        tau_ev, ev = hermite.crossing(c3, c2, c1h, c0, s, 0.0, u_top) * H, 2
    if ev != 0:
        if rs:
            th_e, om_e, v_e = _rk4_rs(theta, omega, v, t, tau_ev, ti, a0x, sx, a0y, sy, s, slip, alpha, r, ig2, mu,
                                      cb, sb)
        else:
            th_e, om_e = _rk4(theta, omega, t, tau_ev, ti, a0x, sx, a0y, sy, s, alpha, k, cb, sb)
            v_e = 0.0
    else:
        th_e, om_e, v_e = theta1, omega1, v1
    c_e, s_e = c_psi, s_psi
    if not rs and ev == 0:  # cos/sin of ψ at the step's end, carried from its start
        c_e, s_e = carry_psi(c_psi, s_psi, theta, theta1, s, alpha, steps)
    tau_r, kind_r, jam = _reaction_event(rs, hold, jam, ev, tau_ev, th_e, om_e, v_e, c_e, s_e, theta, omega, v, t, H,
                                         seg, s, slip, alpha, r, k, ig2, mu, cb, sb)
    hold = False
    motion = (t, theta, omega, v, z, w)
    contact = (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, instant, t_last, t_rest)
    tally = (theta_max, u, u_peak, t_slide, impacts, steps)
    trig = (trig_theta, trig_s, c_psi, s_psi)
    if kind_r >= 0:  # a reaction event before the θ event / step end
        motion, contact, tally = _at_reaction(motion, contact, tally, rs, kind_r, tau_r, u_top, (c3, c2, c1h, c0), H,
                                              seg, alpha, r, k, ig2, mu, cb, sb)
        return 0, motion, contact, tally, trig
    if ev != 0:
        d, motion, contact, tally = _at_theta_event(motion, contact, tally, rs, ev, tau_ev, th_e, om_e, v_e, u_top,
                                                    (c3, c2, c1h, c0), fall, seg, alpha, r, e, ig2, mu, cb, sb)
        return d, motion, contact, tally, trig
    # no event: the whole step
    if omega * omega1 < 0.0:
        u_top = hermite.argmax_scaled(c3, c2, c1h, c0, s)
        theta_max = max(theta_max, abs(hermite.value(c3, c2, c1h, c0, u_top)))
    theta_max = max(theta_max, abs(theta1))
    if rs:
        u += _rs_shift(theta, omega, v, theta1, omega1, v1, t, te - t, ti, a0x, sx, a0y, sy, s, slip, alpha, r,
                       ig2, mu, cb, sb)
        u_peak, t_slide = max(u_peak, abs(u)), t_slide + (te - t)
    else:  # cos/sin of ψ at the new state, for the next step
        trig_theta, trig_s, c_psi, s_psi = theta1, s, c_e, s_e
    theta, omega, v, t = theta1, omega1, v1, te
    return (0, (t, theta, omega, v, z, w), (stage, s, slip, psi_ref, r_ref, fresh, jam, hold, 0, t_last, t_rest),
            (theta_max, u, u_peak, t_slide, impacts, steps), (trig_theta, trig_s, c_psi, s_psi))


@njit(cache=True)
def simulate_general(
    ax: np.ndarray, ay: np.ndarray, env: np.ndarray, dt: float, alpha_p: float, r_p: float, alpha_m: float,
    r_m: float, ig2: float, beta: float, e_p: float, e_m: float, mu: float, n_sub: int, t_after: float,
    fall_plus: float, fall_minus: float, theta0: float, omega0: float, has_vertical: bool,
) -> tuple[int, float, float, int, float, int, int, bool, float, float, float]:
    """Run one scene of the general model. Returns (direction, t_overturn, theta_max, impacts, t_end,
    status, steps, settled_by_prescreen) as :func:`analysis.fast_rocking.simulate_rocking`, then the
    slide (u_peak, u_end, t_slide): the largest |u| [m], u at the end [m] and the time the base or
    the pivot slid [s], u the slide displacement along +x (see ``docs/general-model.md``,
    *Slide displacement*); impacts counts corner impacts and landings. ``alpha_p``, ``r_p`` (``alpha_m``,
    ``r_m``): the slenderness and the distance to the centre of mass [m] of the +x (−x) corner; ``ig2`` i_g² [m²];
    ``e_p`` (``e_m``): the angular-velocity ratio at an impact that ends rocking on the +x (−x) corner; ``mu``
    friction, ``has_vertical``: ``ay`` is not all zero (else the scan does not read it); ``env``:
    ``envelope.block_bounds(ax, ay)`` (the rest scan jumps blocks where no exit can be reached).

    The dispatcher of the stage machine: each pass takes one step of the current stage's step function."""
    n = ax.shape[0]
    t_rec = (n - 1) * dt
    t_stop = t_rec + t_after
    cb, sb = math.cos(beta), math.sin(beta)
    geo = geometry(alpha_p, r_p, alpha_m, r_m, ig2)
    ca_p = geo[4]
    sides = (alpha_p, r_p, geo[2], e_p, alpha_m, r_m, geo[7], e_m)
    h = dt / n_sub
    s = 1.0 if (theta0 > 0.0 or (theta0 == 0.0 and omega0 >= 0.0)) else -1.0
    stage = ST_REST if (theta0 == 0.0 and omega0 == 0.0) else ST_ROCK
    motion = (0.0, theta0, omega0, 0.0, 0.0, 0.0)
    contact = (stage, s, 1.0, alpha_p, r_p, True, False, False, 0, -1.0, 0.0)
    tally = (abs(theta0), 0.0, 0.0, 0.0, 0, 0)
    trig = (math.nan, 0.0, 1.0, 0.0)
    first_scan = True
    i_win = -1  # the record's interval of the last step (step_window's hint)
    it_max = pass_limit(t_stop, dt, n_sub)
    it = 0
    while True:
        it += 1
        t, stage = motion[0], contact[0]
        if it > it_max:
            return _outcome(0, math.nan, t, UNDECIDED, False, tally)
        if stage == ST_REST:
            settled, motion, contact = _rest_step(ax, ay, env, dt, cb, sb, alpha_p, r_p, ca_p, alpha_m, mu,
                                                  has_vertical, motion, contact)
            if settled:  # it ends at rest since t_rest
                return _outcome(0, math.nan, contact[10], REST, first_scan, tally)
            first_scan = False
            continue
        first_scan = False
        if t >= t_stop:
            return _outcome(0, math.nan, t, UNDECIDED, False, tally)
        ti, te, t_b, a0x, sx, a0y, sy, i_win = step_window(ax, ay, dt, h, n_sub, t, t_rec, t_stop, i_win)
        te = min(te, t_stop) if t_stop > t else te
        gx0, gz0 = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
        go, motion, contact = _enter(motion, contact, t_stop, h, gx0, gz0, geo, ig2, mu)
        if not go:
            continue
        stage = contact[0]
        if stage == ST_SLIDE:
            motion, contact, tally = _slide_step(motion, contact, tally, t_b, t_stop, sx, sy, gx0, gz0, cb, sb, mu,
                                                 r_p, ca_p)
            continue
        if stage == ST_FLIGHT:
            d, motion, contact, tally = _flight_step(motion, contact, tally, te - t, sx, sy, gx0, gz0, cb, sb, geo,
                                                     ig2, fall_plus, fall_minus)
        else:
            d, motion, contact, tally, trig = _rock_step(motion, contact, tally, trig, (ti, a0x, sx, a0y, sy), te - t,
                                                         te, sides, ig2, mu, cb, sb, fall_plus, fall_minus)
        if d != 0:
            return _outcome(d, motion[0], motion[0], OVERTURNED, False, tally)
