"""Fast engine, rocking model (Eq. 2): compiled fixed-step RK4 with located events.

One scene = one body, one record (one sign), one angle. What a scene does not need is skipped
(docs/architecture.md §3):

* rest phases cost one scan of Eq. 1's margins, which are linear inside each sample interval
  (the input is piecewise linear), so the next uplift is found exactly — a record that never
  reaches Eq. 1 costs exactly that one scan (the pre-screen);
* a scene stops at overturn;
* chattering (impacts accumulating in finite time when e > 0) is summed analytically once a
  flight is shorter than a quarter step and ends in rest.

Rocking is integrated with classical RK4 on a grid of ``n_sub`` steps per sample interval (so
the input is smooth inside every step); impacts and overturns are located on the step's cubic
Hermite interpolant and the state at an impact is re-integrated with an RK4 step of that length.

A block whose centre of mass is off its centroid rocks on each corner with that corner's slenderness α±,
factor k± = R±/(i_g² + R±²) and impact ratio e± (``analysis.body``): the engine holds the current pivot's three
numbers and changes them only when the pivot changes (uplift, impact), so a step costs what it always did.

Inputs are in SI (m/s²); ``ax``/``ay`` carry one extra trailing zero sample, after which the input
is zero: the free motion is followed for ``t_after`` seconds more or until rest/overturn.
"""

from __future__ import annotations

import math

import numpy as np

from analysis import hermite
from analysis.compiled_index import njit
from analysis.envelope import BLOCK, block_slack, margin_bound
from analysis.equations import plate_gravity, rocking_acceleration, rocking_acceleration_cs, uplift_margins

REST = 0
OVERTURNED = 1
UNDECIDED = 2


@njit(cache=True, inline="always")
def _accel(
    theta: float, t: float, ti: float, a0x: float, sx: float, a0y: float, sy: float,
    s: float, alpha: float, k: float, cb: float, sb: float,
) -> float:
    gx, gz = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
    return rocking_acceleration(theta, s, gx, gz, alpha, k)


RENEW = 64
"""The rocking kernel takes cos ψ and sin ψ from the library every RENEW steps; in between it carries them by
angle addition (rounding of a few ulp per step)."""
SMALL_ANGLE = 0.08
"""|δ| [rad] up to which ``small_sincos`` sums its series (the first term left out is below 3e-18 of the
result, a fortieth of the rounding); beyond it the library's sin and cos are called. A step's offsets are
H·ω, mostly below 0.03."""


@njit(cache=True, inline="always")
def small_sincos(d: float) -> tuple[float, float]:
    """(sin δ, cos δ): Taylor series to δ⁹ / δ⁸ for |δ| ≤ ``SMALL_ANGLE`` (to rounding), else the library's.

    The series are summed in Estrin's order (powers z = δ², z² taken first), three multiply-adds deep instead of
    Horner chains six and seven deep: the RK4 stages wait on them, one after another."""
    if abs(d) > SMALL_ANGLE:
        return math.sin(d), math.cos(d)
    z = d * d
    z2 = z * z
    sn = d * ((1.0 - z * (1.0 / 6.0)) + z2 * ((1.0 / 120.0 - z * (1.0 / 5040.0)) + z2 * (1.0 / 362880.0)))
    cs = (1.0 - 0.5 * z) + z2 * ((1.0 / 24.0 - z * (1.0 / 720.0)) + z2 * (1.0 / 40320.0))
    return sn, cs


@njit(cache=True, inline="always")
def carry_psi(c0: float, s0: float, theta0: float, theta1: float, s: float, alpha: float, steps: int
              ) -> tuple[float, float]:
    """cos ψ, sin ψ at θ1 from their values c0, s0 at θ0 (ψ = α − s θ on pivot ``s``) by the angle-addition
    rule; taken from the library every ``RENEW`` steps (``steps`` counts them), so that rounding cannot pile up."""
    if steps % RENEW == 0:
        return math.cos(alpha - s * theta1), math.sin(alpha - s * theta1)
    sd, cd = small_sincos(theta1 - theta0)
    return c0 * cd + s * s0 * sd, s0 * cd - s * c0 * sd


@njit(cache=True, inline="always")
def _accel_at(
    c0: float, s0: float, d: float, t: float, ti: float, a0x: float, sx: float, a0y: float, sy: float, s: float,
    k: float, cb: float, sb: float,
) -> float:
    """Eq. 2's θ'' at θ = θ0 + δ from cos ψ0, sin ψ0 (ψ0 = α − s θ0): ψ = ψ0 − s δ by the angle-addition rule,
    as ``equations.rocking_acceleration``."""
    sd, cd = small_sincos(d)
    gx, gz = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
    return rocking_acceleration_cs(s, gx, gz, c0 * cd + s * s0 * sd, s0 * cd - s * c0 * sd, k)


@njit(cache=True, inline="always")
def _rk4(
    theta: float, omega: float, t: float, H: float, ti: float, a0x: float, sx: float, a0y: float,
    sy: float, s: float, alpha: float, k: float, cb: float, sb: float,
) -> tuple[float, float]:
    """One classical RK4 step of Eq. 2 of length H [s] from (θ, ω) at t (:func:`_rk4_cs` with ψ's cosine and sine
    taken here)."""
    psi = alpha - s * theta
    return _rk4_cs(theta, omega, math.cos(psi), math.sin(psi), t, H, ti, a0x, sx, a0y, sy, s, k, cb, sb)


@njit(cache=True, inline="always")
def _rk4_cs(
    theta: float, omega: float, c0: float, s0: float, t: float, H: float, ti: float, a0x: float, sx: float,
    a0y: float, sy: float, s: float, k: float, cb: float, sb: float,
) -> tuple[float, float]:
    """One classical RK4 step of Eq. 2 of length H [s] from (θ, ω) at t, given c0, s0 = cos ψ, sin ψ at the
    step's start (ψ = α − s θ); they are carried to the stages by the angle-addition rule (the offsets are
    small)."""
    gx, gz = plate_gravity(a0x + sx * (t - ti), a0y + sy * (t - ti), cb, sb)
    k1 = rocking_acceleration_cs(s, gx, gz, c0, s0, k)
    k2 = _accel_at(c0, s0, 0.5 * H * omega, t + 0.5 * H, ti, a0x, sx, a0y, sy, s, k, cb, sb)
    om2 = omega + 0.5 * H * k1
    k3 = _accel_at(c0, s0, 0.5 * H * om2, t + 0.5 * H, ti, a0x, sx, a0y, sy, s, k, cb, sb)
    om3 = omega + 0.5 * H * k2
    k4 = _accel_at(c0, s0, H * om3, t + H, ti, a0x, sx, a0y, sy, s, k, cb, sb)
    om4 = omega + H * k3
    theta1 = theta + H / 6.0 * (omega + 2.0 * om2 + 2.0 * om3 + om4)
    omega1 = omega + H / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return theta1, omega1


@njit(cache=True, inline="always")
def pivot(s: float, alpha_p: float, k_p: float, e_p: float, alpha_m: float, k_m: float, e_m: float
          ) -> tuple[float, float, float]:
    """(α, k, e) of the pivot ``s``: the + corner's for s > 0, else the − corner's."""
    if s > 0.0:
        return alpha_p, k_p, e_p
    return alpha_m, k_m, e_m


@njit(cache=True)
def _next_uplift(
    ax: np.ndarray, ay: np.ndarray, env: np.ndarray, dt: float, t: float, cb: float, sb: float, ta_p: float,
    ta_m: float,
) -> tuple[float, float]:
    """Earliest time ≥ t at which Eq. 1 is reached (tan α± = ``ta_p``, ``ta_m``), and the side (+1/−1);
    (inf, 0) if never. ``env``: the record's ``envelope.block_bounds``; blocks where neither margin can turn
    positive are jumped."""
    n = ax.shape[0]
    i = int(t / dt)
    if i >= n - 1:
        return math.inf, 0.0
    frac = t / dt - i
    ax_a = ax[i] + (ax[i + 1] - ax[i]) * frac
    ay_a = ay[i] + (ay[i + 1] - ay[i]) * frac
    gx, gz = plate_gravity(ax_a, ay_a, cb, sb)
    mp_a, mm_a = uplift_margins(gx, gz, ta_p, ta_m)
    if mp_a > 0.0:
        return t, 1.0
    if mm_a > 0.0:
        return t, -1.0
    t_a = t
    while i < n - 1:
        j = i + 1
        if j % BLOCK == 0 and j + BLOCK <= n:
            b = env[j // BLOCK]
            lim = block_slack(b[0], b[1], b[2], b[3])
            if (margin_bound(1.0, -ta_p, cb, sb, b[0], b[1], b[2], b[3]) < lim
                    and margin_bound(-1.0, -ta_m, cb, sb, b[0], b[1], b[2], b[3]) < lim):
                i = j + BLOCK - 1
                t_a = i * dt
                gx, gz = plate_gravity(ax[i], ay[i], cb, sb)
                mp_a, mm_a = uplift_margins(gx, gz, ta_p, ta_m)
                continue
        gx, gz = plate_gravity(ax[i + 1], ay[i + 1], cb, sb)
        mp_b, mm_b = uplift_margins(gx, gz, ta_p, ta_m)
        t_b = (i + 1) * dt
        if mp_b > 0.0 or mm_b > 0.0:
            tp = t_a + (t_b - t_a) * mp_a / (mp_a - mp_b) if mp_b > 0.0 else math.inf
            tm = t_a + (t_b - t_a) * mm_a / (mm_a - mm_b) if mm_b > 0.0 else math.inf
            if tp <= tm:
                return tp, 1.0
            return tm, -1.0
        mp_a, mm_a, t_a = mp_b, mm_b, t_b
        i += 1
    return math.inf, 0.0


@njit(cache=True, inline="always")
def pass_limit(t_stop: float, dt: float, n_sub: int) -> int:
    """How many passes of its loop a kernel may take for a scene that ends by ``t_stop`` [s] on a grid of ``n_sub``
    steps per ``dt`` [s]: 64 per step of the grid and room for a million impacts. Past it the scene ends undecided,
    so that no input can hold a kernel in place."""
    return 64 * (int(t_stop / dt) + 2) * n_sub + 1_000_000


@njit(cache=True, inline="always")
def step_window(
    ax: np.ndarray, ay: np.ndarray, dt: float, h: float, n_sub: int, t: float, t_rec: float, t_stop: float,
    i_hint: int,
) -> tuple[float, float, float, float, float, float, float, int]:
    """The next integration step from t on the grid of ``n_sub`` steps per sample interval:
    (ti, te, t_b, a0x, sx, a0y, sy, i) — the interval's start, the step's end, the interval's end
    (``t_stop`` past the record), the input's line a(t) = a0 + slope·(t − ti) on it and the interval's index
    (−1 past the record). Steps never cross a sample, so the piecewise-linear input is smooth inside every step,
    and every step has a length.

    ``i_hint``: the index the previous step returned (−1 if none). The interval is the last one whose start is at
    most t (within 1e-12·dt); where it is the hint's or the next, it is found by the same two products as without a
    hint, without dividing t by dt (a division on every step's path), so the result is the same bit for bit.

    The grid's tests compare a product with a sum (``t_b <= t + tol``), never the difference of a product
    with a number: compiled with fused multiply-adds (as ``simulate_rocking`` is), ``(i + 1)·dt − t`` is taken
    exact while the ``t_b`` returned is rounded, and the two can disagree — a step of zero length for ever (the
    kernel held t at 16.002000000000002 on a 1 kHz record whose interval reads 0.0010000000000000002 s)."""
    n = ax.shape[0]
    if t >= t_rec:
        return t, t + h, t_stop, 0.0, 0.0, 0.0, 0.0, -1
    tol = t + 1e-12 * dt
    i = i_hint
    if i < 0 or i > n - 2 or i * dt > tol:
        i = -1
    elif (i + 1) * dt <= tol:
        i += 1
        if i <= n - 2 and (i + 1) * dt <= tol:
            i = -1
    if i < 0:
        i = int(t / dt)
        if i >= n - 1:
            i = n - 2
        if (i + 1) * dt <= tol:
            i += 1
    ti = i * dt
    if i >= n - 1:
        return ti, t + h, t_stop, 0.0, 0.0, 0.0, 0.0, -1
    t_b = (i + 1) * dt
    if n_sub == 1:
        te = t_b
    else:
        j = int((t - ti) / h + 1e-9) + 1
        te = ti + j * h if j < n_sub else t_b
    if te <= tol:
        te = min(te + h, t_b)
    return ti, te, t_b, ax[i], (ax[i + 1] - ax[i]) / dt, ay[i], (ay[i + 1] - ay[i]) / dt, i


@njit(cache=True, fastmath={"contract"})  # fused multiply-adds: rounding only, 12 % less time per scene
def simulate_rocking(
    ax: np.ndarray, ay: np.ndarray, env: np.ndarray, dt: float, alpha_p: float, k_p: float, alpha_m: float, k_m: float,
    beta: float, e_p: float, e_m: float, n_sub: int, t_after: float, fall_plus: float, fall_minus: float,
    theta0: float, omega0: float,
) -> tuple[int, float, float, int, float, int, int, bool]:
    """Run one scene. Returns (direction, t_overturn, theta_max, impacts, t_end, status, steps,
    settled_by_prescreen); t_end is the overturn time, or the time the body last came to rest.
    ``env``: ``envelope.block_bounds(ax, ay)`` (the rest scan jumps blocks where Eq. 1 cannot be reached).
    ``alpha_p``, ``k_p`` (``alpha_m``, ``k_m``): slenderness and k = R/(i_g² + R²) rocking on the +x (−x)
    corner; ``e_p`` (``e_m``): the angular-velocity ratio at an impact that ends rocking on the +x (−x)
    corner. ``fall_plus``/``fall_minus``: |θ| that counts as overturned towards +x/−x (π/2 for a fall;
    α+ − β / α− + β for the static criterion)."""
    n = ax.shape[0]
    t_rec = (n - 1) * dt
    t_stop = t_rec + t_after
    cb, sb, ta_p, ta_m = math.cos(beta), math.sin(beta), math.tan(alpha_p), math.tan(alpha_m)
    h = dt / n_sub
    t = 0.0
    theta, omega = theta0, omega0
    resting = theta0 == 0.0 and omega0 == 0.0
    s = 1.0 if (theta0 > 0.0 or (theta0 == 0.0 and omega0 >= 0.0)) else -1.0
    alpha, k, e = pivot(s, alpha_p, k_p, e_p, alpha_m, k_m, e_m)
    # cos ψ, sin ψ of the current state (ψ = α − s θ): carried from step to step by angle addition,
    # taken afresh where the pivot changes and every RENEW steps (so rounding cannot pile up)
    c_psi, s_psi = math.cos(alpha - s * theta), math.sin(alpha - s * theta)
    theta_max = abs(theta0)
    impacts = 0
    steps = 0
    first_scan = True
    t_rest = 0.0
    it_max = pass_limit(t_stop, dt, n_sub)
    it = 0
    i_win = -1  # the record's interval of the last step (step_window's hint)
    while True:
        it += 1
        if it > it_max:
            return 0, math.nan, theta_max, impacts, t, UNDECIDED, steps, False
        if resting:
            t_up, side = _next_uplift(ax, ay, env, dt, t, cb, sb, ta_p, ta_m)
            if side == 0.0:
                return 0, math.nan, theta_max, impacts, t_rest, REST, steps, first_scan
            first_scan = False
            t, s, theta, omega, resting = t_up, side, 0.0, 0.0, False
            alpha, k, e = pivot(s, alpha_p, k_p, e_p, alpha_m, k_m, e_m)
            c_psi, s_psi = math.cos(alpha), math.sin(alpha)
        first_scan = False
        if t >= t_stop:
            return 0, math.nan, theta_max, impacts, t, UNDECIDED, steps, False
        ti, te, _, a0x, sx, a0y, sy, i_win = step_window(ax, ay, dt, h, n_sub, t, t_rec, t_stop, i_win)
        H = te - t
        # a short return flight after an impact: sum it analytically (chattering)
        if theta == 0.0 and omega != 0.0:
            acc0 = _accel(0.0, t, ti, a0x, sx, a0y, sy, s, alpha, k, cb, sb)
            if s * acc0 < 0.0 and 2.0 * abs(omega) / abs(acc0) < 0.25 * H:
                t += 2.0 * abs(omega) / abs(acc0)
                impacts += 1
                omega = -e * omega
                if e == 0.0 or abs(omega) < 1e-12:
                    resting, omega, t_rest = True, 0.0, t
                else:
                    s = -s
                    alpha, k, e = pivot(s, alpha_p, k_p, e_p, alpha_m, k_m, e_m)
                    c_psi, s_psi = math.cos(alpha), math.sin(alpha)
                continue
        theta1, omega1 = _rk4_cs(theta, omega, c_psi, s_psi, t, H, ti, a0x, sx, a0y, sy, s, k, cb, sb)
        steps += 1
        fall = fall_plus if s > 0.0 else fall_minus
        if s * theta1 >= fall:
            c3, c2, c1, c0 = hermite.coefficients(theta, omega, theta1, omega1, H)
            u = hermite.crossing(c3, c2, c1, c0, s, fall, 0.0)
            return int(s), t + u * H, fall, impacts, t + u * H, OVERTURNED, steps, False
        if s * theta1 < 0.0 or (theta1 == 0.0 and s * omega1 < 0.0):
            c3, c2, c1, c0 = hermite.coefficients(theta, omega, theta1, omega1, H)
            u_top = hermite.argmax_scaled(c3, c2, c1, c0, s)
            theta_max = max(theta_max, abs(hermite.value(c3, c2, c1, c0, u_top)))
            u = hermite.crossing(c3, c2, c1, c0, s, 0.0, u_top)
            tau = u * H
            _, omega_minus = _rk4(theta, omega, t, tau, ti, a0x, sx, a0y, sy, s, alpha, k, cb, sb)
            t += tau
            impacts += 1
            omega = e * omega_minus
            theta = 0.0
            if e == 0.0 or abs(omega) < 1e-12:
                resting, omega, t_rest = True, 0.0, t
            else:
                s = -s
                alpha, k, e = pivot(s, alpha_p, k_p, e_p, alpha_m, k_m, e_m)
                c_psi, s_psi = math.cos(alpha), math.sin(alpha)
            continue
        if omega * omega1 < 0.0:
            c3, c2, c1, c0 = hermite.coefficients(theta, omega, theta1, omega1, H)
            u_top = hermite.argmax_scaled(c3, c2, c1, c0, s)
            theta_max = max(theta_max, abs(hermite.value(c3, c2, c1, c0, u_top)))
        theta_max = max(theta_max, abs(theta1))
        c_psi, s_psi = carry_psi(c_psi, s_psi, theta, theta1, s, alpha, steps)
        theta, omega, t = theta1, omega1, te
