"""Reference solvers: adaptive high-order integration with every event located exactly.

Used as truth for the fast engine. No shortcuts: the input is piecewise linear between samples
and integrated interval by interval with scipy's ``solve_ivp`` (DOP853, rtol 1e-11, atol 1e-13),
every event (uplift, impact, overturn, stage change) is located by the solver's root finder and
the integration restarted from it. Rest phases are not integrated (nothing moves); the next
uplift is the exact root of Eq. 1's margin, which is linear inside a sample interval.

Conventions as in :mod:`analysis.equations`; inputs here are in m/s² on an explicit time grid
``t`` (non-decreasing; a repeated time is a jump in the input, e.g. a rectangular pulse).
After the last sample the input is zero. A block whose centre of mass is off its centroid takes each
corner's slenderness, k and impact ratio (``alpha``/``k``/``restitution`` for the +x corner, the ``*_minus``
ones for the −x corner; ``analysis.body``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from analysis.equations import (
    plate_gravity,
    rocking_acceleration,
    rocking_acceleration_linear,
    uplift_margins,
)

RTOL = 1e-11
ATOL = 1e-13

EventRoot = Callable[[float, NDArray[np.float64]], float]
"""``root(t [s], y)``: zero where the event happens."""


@dataclass(frozen=True)
class SolverEvent:
    """An event for ``solve_ivp``, which reads ``terminal`` and ``direction`` off each event it is given:
    ``terminal`` stops the integration at the first root; ``direction`` +1 counts only roots where ``root``
    goes from negative to positive, −1 only the opposite, 0 both."""

    root: EventRoot
    terminal: bool
    direction: int

    def __call__(self, t: float, y: NDArray[np.float64]) -> float:
        return self.root(t, y)


def solver_event(*, terminal: bool, direction: int) -> Callable[[EventRoot], SolverEvent]:
    """Decorator: the function below as a :class:`SolverEvent` (``terminal``, ``direction`` as there)."""
    return lambda root: SolverEvent(root, terminal, direction)


@dataclass
class Trace:
    """What a reference run saw: events and, on request, the time history."""

    impacts: list[tuple[float, float, float]] = field(default_factory=list)
    """(t [s], ω before, ω after [rad/s]) at every impact."""
    t: list[float] = field(default_factory=list)
    theta: list[float] = field(default_factory=list)
    omega: list[float] = field(default_factory=list)
    t_rest: float = 0.0
    """When the body last came to rest [s] (0 if it never moved)."""


TraceT = TypeVar("TraceT", bound=Trace, covariant=True)


@dataclass(frozen=True)
class ReferenceOutcome(Generic[TraceT]):
    direction: int
    t_overturn: float | None
    theta_max: float
    t_end: float
    status: str
    trace: TraceT


class _Input:
    """Piecewise-linear ground acceleration on a time grid, zero after the last sample."""

    def __init__(self, t: np.ndarray, ax: np.ndarray, ay: np.ndarray) -> None:
        self.t, self.ax, self.ay = t, ax, ay

    def interval(self, i: int) -> tuple[float, float, float, float, float, float]:
        """(t_a, t_b, ax_a, slope_x, ay_a, slope_y) of interval i (t_b = inf past the end)."""
        if i >= len(self.t) - 1:
            return self.t[-1], math.inf, 0.0, 0.0, 0.0, 0.0
        ta, tb = self.t[i], self.t[i + 1]
        w = tb - ta
        return ta, tb, self.ax[i], (self.ax[i + 1] - self.ax[i]) / w, self.ay[i], (self.ay[i + 1] - self.ay[i]) / w


def simulate_rocking_reference(
    t: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    *,
    alpha: float,
    k: float,
    beta: float,
    restitution: float,
    t_after: float,
    fall_plus: float,
    fall_minus: float,
    theta0: float = 0.0,
    omega0: float = 0.0,
    linearised: bool = False,
    history: bool = False,
    alpha_minus: float | None = None,
    k_minus: float | None = None,
    restitution_minus: float | None = None,
) -> ReferenceOutcome[Trace]:
    """One scene of the rocking model (Eq. 2), or of its linearisation (Housner's linear model).

    ``alpha``, ``k``, ``restitution``: slenderness, k = R/(i_g² + R²) and the impact's angular-velocity ratio
    rocking on the +x corner (the impact that ends that rocking); ``alpha_minus``, ``k_minus``,
    ``restitution_minus`` the −x corner's (None: the same as the +x corner's, a centred block)."""
    acc_fn = rocking_acceleration_linear if linearised else rocking_acceleration
    # the same equations as the compiled engine, called as plain Python (no dispatch per call)
    acc_py, gravity_py = acc_fn.py_func, plate_gravity.py_func
    alpha_m = alpha if alpha_minus is None else alpha_minus
    k_m = k if k_minus is None else k_minus
    e_m = restitution if restitution_minus is None else restitution_minus

    def pivot(side: float) -> tuple[float, float, float]:
        """(α, k, e) rocking on the corner ``side``."""
        return (alpha, k, restitution) if side > 0 else (alpha_m, k_m, e_m)

    cb, sb = math.cos(beta), math.sin(beta)
    inp = _Input(t, ax, ay)
    t_stop = t[-1] + t_after
    trace = Trace()
    theta, omega = theta0, omega0
    resting = theta0 == 0.0 and omega0 == 0.0
    s = 1.0 if (theta0 > 0.0 or (theta0 == 0.0 and omega0 >= 0.0)) else -1.0
    theta_max = abs(theta0)
    now = t[0]
    i = 0
    # margins are linear in time inside an interval: the uplift condition is exact
    uplift_tan = (math.tan(alpha), math.tan(alpha_m)) if not linearised else (alpha, alpha_m)
    gx_all, gz_all = plate_gravity(ax, ay, cb, sb)  # type: ignore[arg-type]  # numba compiles it for arrays too
    mp_all, mm_all = uplift_margins(gx_all, gz_all, *uplift_tan)
    positive = np.flatnonzero((mp_all > 0) | (mm_all > 0))

    while True:
        while i < len(t) - 1 and t[i + 1] <= now:
            i += 1
        t_a, t_b, a0x, sx, a0y, sy = inp.interval(i)
        if resting:
            # every sample from i up to the next positive margin is <= 0, and margins are linear
            # between samples: no uplift before that sample's interval
            nxt = np.searchsorted(positive, i)
            if t_b == math.inf or nxt == positive.size:
                return ReferenceOutcome(0, None, theta_max, trace.t_rest, "rest", trace)
            if positive[nxt] >= i + 2:
                i = int(positive[nxt]) - 1
                now = float(t[i])
                continue
            gxa, gza = plate_gravity(a0x + sx * (now - t_a), a0y + sy * (now - t_a), cb, sb)
            gxb, gzb = plate_gravity(a0x + sx * (t_b - t_a), a0y + sy * (t_b - t_a), cb, sb)
            mpa, mma = uplift_margins(gxa, gza, *uplift_tan)
            mpb, mmb = uplift_margins(gxb, gzb, *uplift_tan)
            cands = []
            if mpa > 0:
                cands.append((now, 1.0))
            elif mpb > 0:
                cands.append((now + (t_b - now) * mpa / (mpa - mpb), 1.0))
            if mma > 0:
                cands.append((now, -1.0))
            elif mmb > 0:
                cands.append((now + (t_b - now) * mma / (mma - mmb), -1.0))
            if not cands:
                now = t_b
                i += 1
                continue
            now, s = min(cands)
            # the root of the margin, nudged past rounding until the rocking equation itself
            # (cos/sin where the margin has tan) pushes the block out on side s
            alpha_s, k_s, _ = pivot(s)
            for _ in range(10_000):
                gx, gz = plate_gravity(a0x + sx * (now - t_a), a0y + sy * (now - t_a), cb, sb)
                if s * acc_fn(0.0, s, gx, gz, alpha_s, k_s) > 0.0 or now >= t_b:
                    break
                now = float(np.nextafter(now, math.inf))
            theta, omega, resting = 0.0, 0.0, False
            continue
        if now >= t_stop:
            return ReferenceOutcome(0, None, theta_max, now, "undecided", trace)

        side = s
        fall = fall_plus if side > 0 else fall_minus
        alpha_s, k_s, e = pivot(side)

        def rhs(tt: float, y: np.ndarray, side: float = side, t_a: float = t_a, a0x: float = a0x,
                sx: float = sx, a0y: float = a0y, sy: float = sy, alpha_s: float = alpha_s,
                k_s: float = k_s) -> list[float]:
            gx, gz = gravity_py(a0x + sx * (tt - t_a), a0y + sy * (tt - t_a), cb, sb)
            return [y[1], acc_py(y[0], side, gx, gz, alpha_s, k_s)]

        @solver_event(terminal=True, direction=-1)
        def ev_impact(tt: float, y: np.ndarray, side: float = side, t0: float = now) -> float:
            # θ = 0 at a restart is where the flight begins, not a return: count it as just
            # outside, so that a return inside the first step is located at its own root
            return side * y[0] if tt > t0 else max(side * y[0], ATOL)

        @solver_event(terminal=True, direction=1)
        def ev_fall(tt: float, y: np.ndarray, side: float = side, fall: float = fall) -> float:
            return side * y[0] - fall

        @solver_event(terminal=False, direction=0)
        def ev_turn(tt: float, y: np.ndarray) -> float:
            return y[1]

        t_end = min(t_b, t_stop)
        sol = solve_ivp(rhs, (now, t_end), [theta, omega], method="DOP853", rtol=RTOL, atol=ATOL,
                        events=[ev_impact, ev_fall, ev_turn])
        if history:
            trace.t.extend(sol.t.tolist())
            trace.theta.extend(sol.y[0].tolist())
            trace.omega.extend(sol.y[1].tolist())
        theta_max = max(theta_max, float(np.max(np.abs(sol.y[0]))))
        for y_turn in sol.y_events[2]:
            theta_max = max(theta_max, abs(float(y_turn[0])))
        if sol.t_events[1].size:
            t_fall = float(sol.t_events[1][0])
            return ReferenceOutcome(int(side), t_fall, max(theta_max, fall), t_fall, "overturned", trace)
        if sol.t_events[0].size:
            t_imp = float(sol.t_events[0][0])
            omega_minus = float(sol.y_events[0][0][1])
            if t_imp <= now and e == 0.0:
                # a lift below the solver's resolution (the margin of Eq. 1 was just positive and
                # is falling): the block stays down until that margin is no longer positive
                theta, omega, resting = 0.0, 0.0, True
                now = _margin_ends(now, t_a, t_b, a0x, sx, a0y, sy, cb, sb, uplift_tan, side)
                trace.t_rest = now
                continue
            now = t_imp
            omega_plus = e * omega_minus
            trace.impacts.append((t_imp, omega_minus, omega_plus))
            theta = 0.0
            if e == 0.0 or _settles(omega_plus, now, inp, i, side, cb, sb, *pivot(-side)[:2], acc_fn):
                resting, omega, trace.t_rest = True, 0.0, now
            else:
                s, omega = -side, omega_plus
            continue
        theta, omega, now = float(sol.y[0, -1]), float(sol.y[1, -1]), t_end


def _margin_ends(now: float, t_a: float, t_b: float, a0x: float, sx: float, a0y: float, sy: float,
                 cb: float, sb: float, tan_alpha: tuple[float, float], side: float) -> float:
    """First time after ``now`` in [now, t_b] at which Eq. 1's margin on ``side`` (linear in time
    here; ``tan_alpha`` = (tan α+, tan α−)) is no longer positive; t_b if it stays positive."""
    def margin(tt: float) -> float:
        gx, gz = plate_gravity.py_func(a0x + sx * (tt - t_a), a0y + sy * (tt - t_a), cb, sb)
        mp, mm = uplift_margins.py_func(gx, gz, *tan_alpha)
        return mp if side > 0 else mm

    m0, m1 = margin(now), margin(t_b)
    if m1 > 0.0:
        return t_b
    tc = now + (t_b - now) * m0 / (m0 - m1) if m0 > 0.0 else now
    return float(np.nextafter(tc, math.inf)) if tc < t_b else t_b


def _settles(omega: float, now: float, inp: _Input, i: int, side: float, cb: float, sb: float,
             alpha: float, k: float, acc_fn) -> bool:
    """Chattering: the next flight on the new pivot (−``side``, whose α and k are ``alpha``, ``k``) is shorter
    than 1e-9 s (the impact sequence has converged to its accumulation point within that), or the rebound
    speed is negligible."""
    if abs(omega) < 1e-12:
        return True
    t_a, _, a0x, sx, a0y, sy = inp.interval(i)
    gx, gz = plate_gravity(a0x + sx * (now - t_a), a0y + sy * (now - t_a), cb, sb)
    acc = acc_fn(0.0, -side, gx, gz, alpha, k)
    return (-side) * acc < 0.0 and 2.0 * abs(omega) / abs(acc) < 1e-9
