"""Reference solver of the general model (Eqs. 3–10): adaptive high-order integration, exact events.

Used as truth for :mod:`analysis.fast_general`; the specification is ``docs/general-model.md``.
No shortcuts: inside each sample interval (the input is piecewise linear) every moving stage is
integrated with scipy's ``solve_ivp`` (DOP853, rtol 1e-11, atol 1e-13), every event (impact,
overturn, slip, lift-off, the slide stopping, landing) is terminal, located by the solver's root
finder, and the integration restarted from it. Rest phases are not integrated (nothing moves):
the next exit from rest is the exact root of the margins, which are linear inside a sample interval.

The transition rules (entry checks, impact rules, the Painlevé/jam and instant-chain guards) are the
fast engine's, so that the two differ only in how they integrate and locate events; the impact rules
themselves are shared compiled functions of :mod:`analysis.fast_general`.

Conventions as in :mod:`analysis.equations`; inputs in m/s² on an explicit time grid ``t``
(non-decreasing; a repeated time is a jump in the input). After the last sample the input is zero.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from analysis.equations import (
    plate_gravity,
    rocking_acceleration,
    rocking_sliding_acceleration,
    sliding_acceleration,
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
    rs_denominator,
)
from analysis.reference import ATOL, RTOL, ReferenceOutcome, Trace, _Input, solver_event

__all__ = ["STAGE_NAMES", "GeneralTrace", "simulate_general_reference"]

STAGE_NAMES = {ST_REST: "rest", ST_SLIDE: "slide", ST_ROCK: "rock", ST_ROCKSLIDE: "rockslide",
               ST_FLIGHT: "flight"}

CHATTER = 1e-9
"""A return flight on the new pivot shorter than this [s] ends the impact sequence in rest."""
HOLD = 1e-9
"""How long [s] the pivot is held without reaction checks to break a chain of instant transitions."""
_AT_START = 1e-300
"""Value of an event that starts at its zero (θ = 0 after an impact, v = 0, the gap at lift-off) at
the restart time itself: on the side it leaves towards, so that a solver step that spans the whole
excursion (out and back) brackets the real crossing and not the restart point."""


@dataclass
class GeneralTrace(Trace):
    """:class:`analysis.reference.Trace` with the general model's extra state in the history.

    Per history sample: ``v`` (tangential velocity relative to the plate of the base in REST/SLIDE,
    of the pivot in ROCK/ROCKSLIDE, of the centre of mass in FLIGHT) [m/s], ``z``/``w`` (height of
    the centre of mass above the plate and its rate, FLIGHT; otherwise the rigid-contact value of z
    and 0) [m, m/s], ``stage`` (ST_* code), ``pivot`` (s, ±1) and ``u`` the slide displacement [m]
    (docs/general-model.md, *Slide displacement*). Always: the slide's ``slide_peak`` (largest |u|)
    [m], ``slide_residual`` (u at the end) [m] and ``slide_time`` (time the base or the pivot slid) [s]."""

    v: list[float] = field(default_factory=list)
    z: list[float] = field(default_factory=list)
    w: list[float] = field(default_factory=list)
    stage: list[int] = field(default_factory=list)
    pivot: list[float] = field(default_factory=list)
    u: list[float] = field(default_factory=list)
    slide_peak: float = 0.0
    slide_residual: float = 0.0
    slide_time: float = 0.0


def simulate_general_reference(
    t: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    *,
    alpha: float,
    r: float,
    ig2: float,
    beta: float,
    restitution: float,
    friction: float,
    t_after: float,
    fall_plus: float,
    fall_minus: float,
    theta0: float = 0.0,
    omega0: float = 0.0,
    history: bool = False,
    alpha_minus: float | None = None,
    r_minus: float | None = None,
    restitution_minus: float | None = None,
) -> ReferenceOutcome[GeneralTrace]:
    """One scene of the general model. ``alpha``, ``r`` [m]: the slenderness and the distance to the centre of
    mass of the +x corner (the half-diagonal of a centred block), ``alpha_minus``, ``r_minus`` the −x corner's
    (None: the same); ``restitution`` (``restitution_minus``): the angular-velocity ratio at an impact that ends
    rocking on the +x (−x) corner; ``ig2`` i_g² [m²], ``friction`` μ."""
    return _Scene(t, ax, ay, alpha, r, ig2, beta, restitution, friction, t_after, fall_plus, fall_minus,
                  history, alpha if alpha_minus is None else alpha_minus, r if r_minus is None else r_minus,
                  restitution if restitution_minus is None else restitution_minus).run(theta0, omega0)


class _Scene:
    def __init__(self, t: np.ndarray, ax: np.ndarray, ay: np.ndarray, alpha: float, r: float, ig2: float,
                 beta: float, e: float, mu: float, t_after: float, fall_plus: float, fall_minus: float,
                 history: bool, alpha_m: float, r_m: float, e_m: float) -> None:
        self.t, self.inp = np.asarray(t, dtype=float), _Input(np.asarray(t, float), np.asarray(ax, float),
                                                               np.asarray(ay, float))
        self.alpha, self.r, self.ig2, self.e, self.mu = alpha, r, ig2, e, mu
        self.alpha_m, self.r_m, self.e_m = alpha_m, r_m, e_m
        # the two corners: (α, R, k, tan α, cos α) of the + corner, then the − corner's (general_stages.geometry)
        self.geo = geometry.py_func(alpha, r, alpha_m, r_m, ig2)
        self.cb, self.sb = math.cos(beta), math.sin(beta)
        self.fall_plus, self.fall_minus = fall_plus, fall_minus
        self.t_stop = float(self.t[-1]) + t_after
        self.history = history
        self.trace = GeneralTrace()

    # ---------------------------------------------------------------------------------------------
    def _record(self, ts: np.ndarray, th: np.ndarray, om: np.ndarray, v: np.ndarray, z: np.ndarray,
                w: np.ndarray, stage: int, s: float, u: np.ndarray) -> None:
        tr = self.trace
        tr.slide_peak = max(tr.slide_peak, float(np.max(np.abs(u))))
        tr.slide_residual = float(u[-1])
        if stage in (ST_SLIDE, ST_ROCKSLIDE):
            tr.slide_time += float(ts[-1] - ts[0])
        if not self.history:
            return
        tr.t.extend(ts.tolist())
        tr.theta.extend(th.tolist())
        tr.omega.extend(om.tolist())
        tr.v.extend(v.tolist())
        tr.z.extend(z.tolist())
        tr.w.extend(w.tolist())
        tr.stage.extend([stage] * len(ts))
        tr.pivot.extend([s] * len(ts))
        tr.u.extend(u.tolist())

    def pivot(self, s: float) -> tuple[float, float, float, float]:
        """(α, R, k, e) of the corner ``s``: e the angular-velocity ratio at an impact that ends rocking on it."""
        alpha, r, k, _, _ = corner(self.geo, s)
        return alpha, r, k, (self.e if s > 0 else self.e_m)

    def run(self, theta0: float, omega0: float) -> ReferenceOutcome[GeneralTrace]:
        ig2, mu, geo = self.ig2, self.mu, self.geo
        alpha_p, r_p, alpha_m, r_m = self.alpha, self.r, self.alpha_m, self.r_m
        cb, sb = self.cb, self.sb
        t, inp, trace = self.t, self.inp, self.trace
        t_stop = self.t_stop
        theta, omega, v, z, w = theta0, omega0, 0.0, 0.0, 0.0
        u = 0.0  # slide displacement [m]
        s = 1.0 if (theta0 > 0.0 or (theta0 == 0.0 and omega0 >= 0.0)) else -1.0
        slip = 1.0
        stage = ST_REST if (theta0 == 0.0 and omega0 == 0.0) else ST_ROCK
        theta_max = abs(theta0)
        fresh, jam, hold = True, False, False
        instant, t_last = 0, -math.inf
        now = float(t[0])
        i = 0
        n_iter = 0
        max_iter = 20 * len(t) + 20_000
        ca_p, sa_p, ca_m, sa_m = math.cos(alpha_p), math.sin(alpha_p), math.cos(alpha_m), math.sin(alpha_m)
        tips_p, tips_m = friction_tips(mu, geo[3]), friction_tips(mu, geo[8])
        psi_ref, r_ref = alpha_p, r_p

        def done(direction: int, t_o: float | None, status: str, t_end: float) -> ReferenceOutcome[GeneralTrace]:
            return ReferenceOutcome(direction, t_o, theta_max, t_end, status, trace)

        while True:
            n_iter += 1
            if n_iter > max_iter:
                return done(0, None, "undecided", now)
            while i < len(t) - 1 and t[i + 1] <= now:
                i += 1
            t_a, t_b, a0x, sx, a0y, sy = inp.interval(i)

            def grav(tt: float, t_a: float = t_a, a0x: float = a0x, sx: float = sx, a0y: float = a0y,
                     sy: float = sy) -> tuple[float, float]:
                return plate_gravity(a0x + sx * (tt - t_a), a0y + sy * (tt - t_a), cb, sb)

            # ============================================================ REST: exact exit
            if stage == ST_REST:
                if t_b == math.inf:
                    kind = rest_exit(*rest_margins(0.0, 0.0, cb, sb, ca_p, sa_p, ca_m, sa_m, mu), tips_p, tips_m)
                    if kind == EXIT_NONE:
                        return done(0, None, "rest", trace.t_rest)
                    t_x = now
                else:
                    t_x, kind = rest_leave(now, t_b, t_a, a0x, sx, a0y, sy, float(inp.ax[i + 1]),
                                           float(inp.ay[i + 1]), cb, sb, ca_p, sa_p, ca_m, sa_m, mu, tips_p,
                                           tips_m)
                    if kind == EXIT_NONE:
                        now = t_b
                        i += 1
                        continue
                now = t_x
                theta = omega = v = w = 0.0
                jam = False
                stage, s, slip, z = leave_rest(kind, s, slip, z, r_p, ca_p)
                fresh = True
                instant = instant + 1 if now == t_last else 0
                t_last = now
                continue

            if now >= t_stop:
                return done(0, None, "undecided", now)
            t_end = min(t_b, t_stop)
            gx0, gz0 = grav(now)

            # ---- a chain of transitions that take no time: hold the pivot briefly
            if fresh and instant > MAX_INSTANT:
                instant = 0
                stage, s = break_instant_chain(stage, theta, omega, v, s)
                if stage == ST_ROCK:
                    hold, fresh, v = True, False, 0.0
                elif stage == ST_REST:  # it rests for HOLD before its next exit
                    theta = omega = v = w = 0.0
                    trace.t_rest = now
                    now = min(now + HOLD, t_stop)
                    continue

            # ---- entry conditions (instant transitions)
            if fresh:
                fresh = False
                new, theta, omega, v, w, z, s, slip, hold, jam, psi_ref, r_ref = enter_stage(
                    stage, hold, jam, theta, omega, v, w, z, s, slip, psi_ref, r_ref, gx0, gz0, geo, ig2, mu)
                if new != stage:
                    stage = new
                    fresh = True
                    instant = instant + 1 if now == t_last else 0
                    t_last = now
                    if stage == ST_REST:
                        trace.t_rest = now
                    continue

            def transition(t_new: float) -> None:
                nonlocal fresh, instant, t_last
                fresh = True
                instant = instant + 1 if t_new == t_last else 0
                t_last = t_new

            # ============================================================ SLIDE
            if stage == ST_SLIDE:
                sl = slip

                def rhs_slide(tt: float, y: np.ndarray, sl: float = sl) -> list[float]:
                    gx, gz = grav(tt)
                    return [sliding_acceleration(sl, gx, gz, mu), y[0]]

                @solver_event(terminal=True, direction=-1)
                def ev_stop(tt: float, y: np.ndarray, sl: float = sl, t0: float = now) -> float:
                    return sl * y[0] if tt != t0 else _AT_START

                @solver_event(terminal=True, direction=-1)
                def ev_lift(tt: float, y: np.ndarray) -> float:
                    gz = grav(tt)[1]  # lifts off when g_z < 0: at g_z = 0 the weightless block slides
                    return gz if gz != 0.0 else _AT_START

                sol = solve_ivp(rhs_slide, (now, t_end), [v, u], method="DOP853", rtol=RTOL, atol=ATOL,
                                events=[ev_stop, ev_lift])
                n_pts = sol.t.size
                zeros = np.zeros(n_pts)
                stops = bool(sol.t_events[0].size) and (
                    not sol.t_events[1].size or sol.t_events[0][0] <= sol.t_events[1][0])
                v_rec = sol.y[0].copy()
                if stops:  # the slide ends where v = 0: the point recorded there is the rest that follows, not
                    v_rec[-1] = 0.0  # the root's rounding (|v| ~ 1e-16 of either sign, by the SciPy release)
                self._record(sol.t, zeros, zeros, v_rec, np.full(n_pts, r_p * ca_p), zeros, ST_SLIDE, s, sol.y[1])
                if stops:
                    now, v, u = float(sol.t_events[0][0]), 0.0, float(sol.y_events[0][0][1])
                    stage, trace.t_rest = ST_REST, now
                    transition(now)
                elif sol.t_events[1].size:
                    now, v, u = float(sol.t_events[1][0]), float(sol.y_events[1][0][0]), float(sol.y_events[1][0][1])
                    stage, theta, omega, w, z = ST_FLIGHT, 0.0, 0.0, 0.0, r_p * ca_p
                    transition(now)
                else:
                    now, v, u = t_end, float(sol.y[0, -1]), float(sol.y[1, -1])
                continue

            # ============================================================ FLIGHT
            if stage == ST_FLIGHT:
                fp, fm = self.fall_plus, self.fall_minus

                def rhs_flight(tt: float, y: np.ndarray) -> list[float]:  # y[5]: x_G, the centre of mass
                    gx, gz = grav(tt)
                    return [y[1], 0.0, gx, y[4], -gz, y[2]]

                @solver_event(terminal=True, direction=-1)
                def ev_land(tt: float, y: np.ndarray, psi_ref: float = psi_ref, r_ref: float = r_ref,
                            t0: float = now) -> float:
                    # gap of the lowest corner (sign θ), ζ − r (cos ψ − cos ψ_ref): no cancellation at lift-off;
                    # ζ − (r cos ψ − r_ref cos ψ_ref) once θ has changed sign on a body with unlike corners
                    if tt == t0:
                        return _AT_START
                    alpha, r = (alpha_p, r_p) if y[0] >= 0.0 else (alpha_m, r_m)
                    psi = alpha - abs(y[0])
                    if r == r_ref:
                        return y[3] + 2.0 * r * math.sin(0.5 * (psi + psi_ref)) * math.sin(0.5 * (psi - psi_ref))
                    return y[3] - (r * math.cos(psi) - r_ref * math.cos(psi_ref))

                @solver_event(terminal=True, direction=1)
                def ev_fp(tt: float, y: np.ndarray, fp: float = fp) -> float:
                    return y[0] - fp

                @solver_event(terminal=True, direction=1)
                def ev_fm(tt: float, y: np.ndarray, fm: float = fm) -> float:
                    return -y[0] - fm

                def lean(th: float) -> float:
                    return lean_offset(th, alpha_p, r_p, alpha_m, r_m)

                sol = solve_ivp(rhs_flight, (now, t_end), [theta, omega, v, z, w, u - lean(theta)],
                                method="DOP853", rtol=RTOL, atol=ATOL, events=[ev_land, ev_fp, ev_fm])
                self._record(sol.t, sol.y[0], sol.y[1], sol.y[2], sol.y[3] + r_ref * math.cos(psi_ref), sol.y[4],
                             ST_FLIGHT, s, sol.y[5] + np.array([lean(th) for th in sol.y[0]]))
                theta_max = max(theta_max, float(np.max(np.abs(sol.y[0]))))
                evs = [(float(te[0]), j) for j, te in enumerate(sol.t_events) if te.size]
                if not evs:
                    theta, omega, v, z, w, x_g = (float(x) for x in sol.y[:, -1])
                    u = x_g + lean(theta)
                    now = t_end
                    continue
                t_ev, j = min(evs)
                y = sol.y_events[j][0]
                u = float(y[5]) + lean(float(y[0]))
                trace.slide_peak, trace.slide_residual = max(trace.slide_peak, abs(u)), u
                if j > 0:
                    d = 1 if j == 1 else -1
                    theta_max = max(theta_max, fp if d > 0 else fm)
                    return done(d, t_ev, "overturned", t_ev)
                theta, omega, v, z, w, _ = (float(x) for x in y)
                now = t_ev
                if abs(theta) < FLAT:
                    trace.impacts.append((now, omega, 0.0))
                    theta = omega = w = 0.0
                    if v == 0.0:
                        stage, trace.t_rest = ST_REST, now
                    else:
                        stage, slip = ST_SLIDE, (1.0 if v > 0.0 else -1.0)
                else:
                    s = 1.0 if theta > 0.0 else -1.0
                    om_p = landing_omega(theta, omega, v, w, *corner(geo, s)[:2], ig2)
                    trace.impacts.append((now, omega, om_p))
                    omega = om_p
                    stage, v, jam = ST_ROCK, 0.0, False
                transition(now)
                continue

            # ============================================================ ROCK / ROCKSLIDE
            rs = stage == ST_ROCKSLIDE
            side, sl = s, slip
            alpha, r, k, e = self.pivot(side)  # the pivot's corner
            fall = self.fall_plus if side > 0 else self.fall_minus
            if stage == ST_ROCK and jam:
                f, _, _ = rock_margin(theta, omega, side, gx0, gz0, alpha, r, k, mu)
                if f <= 0.0:
                    jam = False
            jam_now, hold_now = jam, hold
            t_seg = min(t_end, now + HOLD) if hold_now else t_end
            hold = False

            rhs: Callable[[float, np.ndarray], list[float]]
            if rs:
                def rhs_rockslide(tt: float, y: np.ndarray, side: float = side, sl: float = sl, alpha: float = alpha,
                                  r: float = r) -> list[float]:
                    gx, gz = grav(tt)
                    th_dd, x_dd, _ = rocking_sliding_acceleration(y[0], y[1], side, sl, gx, gz, alpha, r, ig2, mu)
                    return [y[1], th_dd, x_dd, y[2]]
                rhs = rhs_rockslide
            else:
                def rhs_rock(tt: float, y: np.ndarray, side: float = side, alpha: float = alpha,
                             k: float = k) -> list[float]:
                    gx, gz = grav(tt)
                    return [y[1], rocking_acceleration(y[0], side, gx, gz, alpha, k)]
                rhs = rhs_rock

            @solver_event(terminal=True, direction=-1)
            def ev_impact(tt: float, y: np.ndarray, side: float = side, t0: float = now) -> float:
                return side * y[0] if tt != t0 else _AT_START

            @solver_event(terminal=True, direction=1)
            def ev_fall(tt: float, y: np.ndarray, side: float = side, fall: float = fall) -> float:
                return side * y[0] - fall

            @solver_event(terminal=False, direction=0)
            def ev_turn(tt: float, y: np.ndarray) -> float:
                return y[1]

            events = [ev_impact, ev_fall, ev_turn]
            if rs:
                @solver_event(terminal=True, direction=-1)
                def ev_pivot_stop(tt: float, y: np.ndarray, sl: float = sl, t0: float = now) -> float:
                    return sl * y[2] if tt != t0 else _AT_START

                @solver_event(terminal=True, direction=1)
                def ev_pivot_lift(tt: float, y: np.ndarray, side: float = side, sl: float = sl, alpha: float = alpha,
                                  r: float = r) -> float:  # R_n < 0
                    gx, gz = grav(tt)
                    return -rocking_sliding_acceleration(y[0], y[1], side, sl, gx, gz, alpha, r, ig2, mu)[2]

                @solver_event(terminal=True, direction=-1)
                def ev_painleve(tt: float, y: np.ndarray, side: float = side, sl: float = sl, alpha: float = alpha,
                                r: float = r) -> float:
                    return rs_denominator(y[0], side, sl, alpha, r, ig2, mu) - DEN_MIN * (ig2 + r * r)

                events += [ev_pivot_stop, ev_pivot_lift, ev_painleve]
                y0 = [theta, omega, v, u]
            else:
                if not hold_now:
                    @solver_event(terminal=True, direction=1)
                    def ev_react(tt: float, y: np.ndarray, side: float = side, jam_now: bool = jam_now,
                                 alpha: float = alpha, r: float = r, k: float = k) -> float:
                        gx, gz = grav(tt)
                        f, _, rn = rock_margin(y[0], y[1], side, gx, gz, alpha, r, k, mu)
                        return -rn if jam_now else f

                    events.append(ev_react)
                y0 = [theta, omega]

            sol = solve_ivp(rhs, (now, t_seg), y0, method="DOP853", rtol=RTOL, atol=ATOL, events=events)
            evs = [(float(sol.t_events[j][0]), j) for j in range(len(events))
                   if j != 2 and sol.t_events[j].size]
            first = min(evs) if evs else None
            stops = rs and first is not None and first[1] == 3  # the sliding pivot stops (ev_pivot_stop)
            vv = sol.y[2].copy() if rs else np.zeros(sol.t.size)
            if stops:  # as in SLIDE: the point recorded where v = 0 holds 0, not the root's rounding
                vv[-1] = 0.0
            self._record(sol.t, sol.y[0], sol.y[1], vv, r * np.cos(alpha - np.abs(sol.y[0])), np.zeros(sol.t.size),
                         stage, side, sol.y[3] if rs else np.full(sol.t.size, u))
            theta_max = max(theta_max, float(np.max(np.abs(sol.y[0]))))
            for y_turn in sol.y_events[2]:
                theta_max = max(theta_max, abs(float(y_turn[0])))
            if first is None:
                theta, omega = float(sol.y[0, -1]), float(sol.y[1, -1])
                v = float(sol.y[2, -1]) if rs else 0.0
                u = float(sol.y[3, -1]) if rs else u
                now = t_seg
                fresh = hold_now  # after a hold, the reactions are checked again at once
                continue
            t_ev, j = first
            y = sol.y_events[j][0]
            theta, omega = float(y[0]), float(y[1])
            v = 0.0 if stops or not rs else float(y[2])
            if rs:
                u = float(y[3])
                trace.slide_peak, trace.slide_residual = max(trace.slide_peak, abs(u)), u
            now = t_ev
            if j == 1:  # overturn
                theta_max = max(theta_max, fall)
                return done(int(side), t_ev, "overturned", t_ev)
            gx, gz = grav(now)
            if j == 0:  # corner impact
                omega_minus = omega
                vp = corner_impact_velocity(v, omega_minus, e, r, alpha) if rs else 0.0
                omega_plus = e * omega_minus
                trace.impacts.append((now, omega_minus, omega_plus))
                theta = 0.0
                if e == 0.0 or self._settles(omega_plus, -side, vp, gx, gz):
                    omega = 0.0
                    if vp == 0.0:
                        stage, trace.t_rest, v = ST_REST, now, 0.0
                    else:
                        stage, v, slip = ST_SLIDE, vp, (1.0 if vp > 0.0 else -1.0)
                else:
                    s, omega, jam = -side, omega_plus, False
                    if vp == 0.0:
                        stage, v = ST_ROCK, 0.0
                    else:
                        stage, v, slip = ST_ROCKSLIDE, vp, (1.0 if vp > 0.0 else -1.0)
            elif rs and j == 4:  # lift-off
                z, v, w = flight_entry(theta, omega, v, side, alpha, r)
                stage = ST_FLIGHT
            elif rs and j == 5:  # Painlevé ahead: the pivot sticks
                stage, v, jam = ST_ROCK, 0.0, True
            else:  # ROCK's reactions, or the slide stops: stick, slide (the other way) or fly
                stage, v, w, z, slip, jam, hold = after_reaction(theta, omega, v, w, z, side, sl, jam, rs, gx, gz,
                                                                 alpha, r, ig2, k, mu)
            transition(now)
            if hold:
                fresh = False

    def _settles(self, omega: float, side: float, v: float, gx: float, gz: float) -> bool:
        """Chattering: the next return flight on the new pivot ``side`` is shorter than 1e-9 s, or the
        rebound speed is negligible."""
        if abs(omega) < 1e-12:
            return True
        alpha, r, k, _ = self.pivot(side)
        if v == 0.0:
            acc = rocking_acceleration(0.0, side, gx, gz, alpha, k)
        else:
            acc = rocking_sliding_acceleration(0.0, omega, side, 1.0 if v > 0.0 else -1.0, gx, gz, alpha,
                                               r, self.ig2, self.mu)[0]
        return side * acc < 0.0 and 2.0 * abs(omega) / abs(acc) < CHATTER

