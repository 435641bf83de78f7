"""The general model's stages and the rules that move a block between them, shared by both engines.

:mod:`analysis.fast_general` (compiled) and :mod:`analysis.reference_general` (scipy ``solve_ivp``)
integrate the stages REST/SLIDE/ROCK/ROCKSLIDE/FLIGHT differently, but decide the transitions with the
same rules, written once here: the exit a resting block takes (:func:`rest_margins`, :func:`rest_exit`,
:func:`leave_rest`), the checks made when a stage is entered (:func:`enter_stage`, after
docs/general-model.md), and how a chain of transitions that take no time is broken
(:func:`break_instant_chain`). Every function is compiled with numba (the fast engine calls them from
its kernel; the reference calls the same compiled functions from Python), so both engines take the
same branch on the same numbers.

Conventions are those of :mod:`analysis.equations`: θ [rad] positive rocking on the + pivot
(``s`` = +1), ψ = α − s θ, ``slip`` = ±1 the sign of the pivot's sliding velocity ``v`` [m/s] along the
plate, ``z``/``w`` [m, m/s] the centre of mass's height and vertical velocity in flight, ``gx``/``gz``
[m/s²] the plate-frame gravity minus input (:func:`analysis.equations.plate_gravity`).

Each corner has its own slenderness α± and distance R± to the centre of mass (``analysis.body``: they differ
when the centre of mass is off the middle). A function of one pivot ``s`` takes that pivot's ``alpha`` and
``r`` (and ``k`` = r/(i_g² + r²)); those that may meet either corner take the body's ``geo``
(:func:`geometry`: α, R, k, tan α, cos α of the + corner, then of the − corner). A landing or the lean of a
block in flight is on the corner sign θ, the lowest one; at θ = 0 both corners give the resting height of the
centre of mass, h_cg = R± cos α±.
"""

from __future__ import annotations

import math

from analysis.compiled_index import njit
from analysis.equations import (
    pivot_reactions_cs,
    plate_gravity,
    rocking_acceleration_cs,
    rocking_sliding_acceleration,
)

# stages
ST_REST = 0
ST_SLIDE = 1
ST_ROCK = 2
ST_ROCKSLIDE = 3
ST_FLIGHT = 4

# exits from REST (rest_exit)
EXIT_NONE = 0
EXIT_ROCK_PLUS = 1
EXIT_ROCK_MINUS = 2
EXIT_SLIDE_PLUS = 3
EXIT_SLIDE_MINUS = 4
EXIT_FLIGHT = 5

FLAT = 1e-9
"""|θ| [rad] below which a landing is flat (docs/general-model.md)."""
DEN_MIN = 1e-3
"""Smallest accepted denominator of Eq. 9, relative to i_g² + r² (Painlevé guard)."""
MAX_INSTANT = 12
"""Transitions in a row that take no time before the pivot is held for one step."""
TIE = 1e-12
"""Relative band around μ = tan α = b/h inside which friction and slenderness tie: the block slides
(:func:`friction_tips`, docs/general-model.md, *Ties*)."""


# --------------------------------------------------------------------------------------------------
# the two corners


@njit(cache=True)
def geometry(alpha_p: float, r_p: float, alpha_m: float, r_m: float, ig2: float
             ) -> tuple[float, float, float, float, float, float, float, float, float, float]:
    """``geo``: (α, R, k, tan α, cos α) of the + corner, then of the − corner; k = R/(i_g² + R²)."""
    return (alpha_p, r_p, r_p / (ig2 + r_p * r_p), math.tan(alpha_p), math.cos(alpha_p),
            alpha_m, r_m, r_m / (ig2 + r_m * r_m), math.tan(alpha_m), math.cos(alpha_m))


@njit(cache=True, inline="always")
def corner(geo: tuple, s: float) -> tuple[float, float, float, float, float]:
    """(α, R, k, tan α, cos α) of the corner ``s`` (+1: the + corner; else the − corner)."""
    if s > 0.0:
        return geo[0], geo[1], geo[2], geo[3], geo[4]
    return geo[5], geo[6], geo[7], geo[8], geo[9]


# --------------------------------------------------------------------------------------------------
# transitions


@njit(cache=True)
def rs_denominator(theta: float, s: float, slip: float, alpha: float, r: float, ig2: float, mu: float) -> float:
    """Denominator of Eq. 9, i_g² + r² sin ψ (sin ψ − μ s slip cos ψ) [m²]; ≤ 0: Painlevé.
    ψ = α − s θ, as in :mod:`analysis.equations`."""
    psi = alpha - s * theta
    sn = math.sin(psi)
    return ig2 + r * r * sn * (sn - mu * s * slip * math.cos(psi))


@njit(cache=True)
def corner_impact_velocity(v: float, omega_minus: float, e: float, r: float, alpha: float) -> float:
    """Sliding velocity of the base (new pivot) after a corner impact at θ = 0 of a sliding pivot.

    docs/general-model.md keeps the pivot's velocity v. That is the tangential impulse of the
    sticking rocking impact, r cos α (e − 1) ω⁻ per unit mass, and it is kept when it opposes the
    slide (v ω⁻ ≥ 0). When v ω⁻ < 0 that impulse would push the sliding corner *along* its slide
    (a friction impulse doing positive work: the kinetic energy can grow); then no tangential impulse
    acts (the centre of mass keeps its tangential velocity), v⁺ = v + r cos α (1 − e) ω⁻, and friction
    stops the slide rather than reverse it (v⁺ = 0 if the sign would change). Both branches never
    increase the kinetic energy, and v = 0 (ROCK) gives v⁺ = 0: the rocking model's impact.
    """
    if v == 0.0 or v * omega_minus >= 0.0:
        return v
    vp = v + r * math.cos(alpha) * (1.0 - e) * omega_minus
    if vp * v <= 0.0:
        return 0.0
    return vp


@njit(cache=True)
def landing_omega(theta: float, omega: float, v: float, w: float, alpha: float, r: float, ig2: float) -> float:
    """θ' after a plastic, sticking landing on the corner s = sign θ (angular momentum about it); ``alpha``, ``r``
    that corner's."""
    s = 1.0 if theta > 0.0 else -1.0
    psi = alpha - abs(theta)
    dx = -s * r * math.sin(psi)
    dz = r * math.cos(psi)
    wz = (ig2 * (-omega) + dx * w - dz * v) / (ig2 + r * r)
    return -wz


@njit(cache=True, inline="always")
def lean_offset(theta: float, alpha_p: float, r_p: float, alpha_m: float, r_m: float) -> float:
    """u − x_G + const [m]: the slide displacement u (docs/general-model.md, *Slide displacement*) is where the
    base centre lies once the block is laid flat about the corner it leans on (s = sign θ), x_G the centre
    of mass: s · R_s (sin(α_s − |θ|) − sin α_s) (+ b/2 − b_cg, a constant, left out: u is only ever moved by
    differences of this); 0 when flat, continuous through θ = 0."""
    if theta == 0.0:
        return 0.0
    if theta > 0.0:
        return r_p * (math.sin(alpha_p - theta) - math.sin(alpha_p))
    return -1.0 * r_m * (math.sin(alpha_m + theta) - math.sin(alpha_m))


@njit(cache=True)
def flight_entry(theta: float, omega: float, v_pivot: float, s: float, alpha: float, r: float
                 ) -> tuple[float, float, float]:
    """(z, v, w) of the centre of mass when the pivot ``s`` leaves the plate."""
    psi = alpha - s * theta
    return r * math.cos(psi), v_pivot + omega * r * math.cos(psi), s * omega * r * math.sin(psi)


@njit(cache=True)
def rock_margin(theta: float, omega: float, s: float, gx: float, gz: float, alpha: float, r: float,
                k: float, mu: float) -> tuple[float, float, float]:
    """(|R_t| − μ R_n, R_t, R_n) of a pivot that does not slip."""
    psi = alpha - s * theta
    return rock_margin_cs(omega, s, gx, gz, math.cos(psi), math.sin(psi), r, k, mu)


@njit(cache=True, inline="always")
def rock_margin_cs(omega: float, s: float, gx: float, gz: float, c: float, sn: float, r: float, k: float,
                   mu: float) -> tuple[float, float, float]:
    """``rock_margin`` from c, sn = cos ψ, sin ψ of the state (ψ = α − s θ), as Eq. 2 and the reactions take them."""
    add = rocking_acceleration_cs(s, gx, gz, c, sn, k)
    rt, rn = pivot_reactions_cs(omega, add, s, gx, gz, c, sn, r)
    return abs(rt) - mu * rn, rt, rn


@njit(cache=True)
def rockslide_entry(theta: float, omega: float, v: float, s: float, slip: float, gx: float, gz: float,
                    alpha: float, r: float, ig2: float, mu: float) -> int:
    """Can the pivot ``s`` slide with sign ``slip`` from this state? 0 yes, 1 it lifts off (R_n ≤ 0),
    2 it cannot (Painlevé: the denominator of Eq. 9 is not positive).

    From v = 0 the direction is the one the no-slip reaction demands (slip = −sign R_t where
    |R_t| > μ R_n); with a positive denominator that slide is the consistent one (at the onset
    |R_t| = μ R_n the pivot's acceleration is 0 and grows with sign ``slip``), so it is not rechecked.
    """
    if rs_denominator(theta, s, slip, alpha, r, ig2, mu) <= DEN_MIN * (ig2 + r * r):
        return 2
    _, _, rn = rocking_sliding_acceleration(theta, omega, s, slip, gx, gz, alpha, r, ig2, mu)
    if rn <= 0.0:
        return 1
    return 0


ROCK_STAY = 0
ROCK_TO_ROCKSLIDE = 1
ROCK_TO_FLIGHT = 2
ROCK_JAM = 3
ROCK_HOLD = 4


@njit(cache=True)
def rock_exit(theta: float, omega: float, s: float, gx: float, gz: float, alpha: float, r: float, ig2: float,
              k: float, mu: float, jam: bool) -> tuple[int, float]:
    """What a pivot that does not slip does now: (ROCK_*, slip direction).

    It stays while |R_t| ≤ μ R_n (only R_n ≥ 0 is checked when ``jam``). Otherwise it slides with
    slip = −sign R_t, unless that slide lifts off: with a positive denominator of Eq. 9 the sliding
    pivot's R_n = −X i_g²/den, where X = r cos ψ ω² − g_z is the normal acceleration the corner would
    have in free flight, so lift-off (R_n ≤ 0) is exactly when a flight is consistent (X ≥ 0). The
    no-slip R_n alone is not that test (it carries the moment of the sticking friction): a no-slip
    R_n < 0 with X < 0 would fly into the plate. A Painlevé pivot (denominator ≤ 0) flies if X > 0,
    else it sticks (ROCK_JAM), or, when even its no-slip R_n < 0, is held for a step (ROCK_HOLD).
    """
    f, rt, rn = rock_margin(theta, omega, s, gx, gz, alpha, r, k, mu)
    x_free = r * math.cos(alpha - s * theta) * omega * omega - gz
    sl = -1.0 if rt > 0.0 else 1.0
    if jam:
        if rn >= 0.0:
            return ROCK_STAY, sl
        return (ROCK_TO_FLIGHT, sl) if x_free > 0.0 else (ROCK_HOLD, sl)
    if f <= 0.0:
        return ROCK_STAY, sl
    code = rockslide_entry(theta, omega, 0.0, s, sl, gx, gz, alpha, r, ig2, mu)
    if code == 0:
        return ROCK_TO_ROCKSLIDE, sl
    if code == 1 or x_free > 0.0:
        return ROCK_TO_FLIGHT, sl
    return (ROCK_JAM, sl) if rn >= 0.0 else (ROCK_HOLD, sl)


@njit(cache=True, inline="always")
def rest_margins(ax_: float, ay_: float, cb: float, sb: float, ca_p: float, sa_p: float, ca_m: float, sa_m: float,
                 mu: float) -> tuple[float, float, float, float, float]:
    """The five REST margins (> 0: that exit is reached): uplift +/− (Eq. 1 times cos α±, written as
    the rocking equation's θ'' at θ = 0 over k, so that a positive margin always starts a rotation —
    the tan α form can be positive by rounding while θ'' is 0; ``ca_p``/``sa_p`` = cos α+, sin α+, ``ca_m``/
    ``sa_m`` the − corner's), slide +/−, lift-off (−gz)."""
    gx, gz = plate_gravity(ax_, ay_, cb, sb)
    return gx * ca_p - gz * sa_p, -gx * ca_m - gz * sa_m, gx - mu * gz, -gx - mu * gz, -gz


@njit(cache=True, inline="always")
def friction_tips(mu: float, ta: float) -> bool:
    """μ > tan α = b/h beyond the tie band ``TIE``: a block pushed past its threshold towards a corner
    rocks on it (that REST exit is the uplift) and friction tips a block sliding towards that corner over
    it. At the tie (|μ − b/h| within ``TIE`` b/h) and below, it slides (docs/general-model.md, *Ties*).
    Per corner: ``ta`` = tan α± = d±/h_cg of the corner the push or the slide goes towards."""
    return mu > ta * (1.0 + TIE)


@njit(cache=True, inline="always")
def rest_exit(m1: float, m2: float, m3: float, m4: float, m5: float, tips_p: bool, tips_m: bool) -> int:
    """The exit among the positive margins: lift-off first; then towards +x, when friction tips on the + corner
    (``tips_p``, :func:`friction_tips`) and g_z > 0, the uplift m1, else the slide m3; then towards −x the same
    with ``tips_m``, m2 and m4. Mathematically an uplift margin > 0 implies that side's slide margin > 0 when
    μ ≤ tan α±, and a slide margin > 0 implies the uplift when μ > tan α±, so the other margin only decides by
    rounding: it is not read."""
    if m5 > 0.0:
        return EXIT_FLIGHT
    # a weightless block (g_z = 0) has no normal force to pivot on: it slides
    if tips_p and m5 < 0.0:
        if m1 > 0.0:
            return EXIT_ROCK_PLUS
    elif m3 > 0.0:
        return EXIT_SLIDE_PLUS
    if tips_m and m5 < 0.0:
        return EXIT_ROCK_MINUS if m2 > 0.0 else EXIT_NONE
    return EXIT_SLIDE_MINUS if m4 > 0.0 else EXIT_NONE


@njit(cache=True)
def rest_leave(t0: float, t1: float, tl: float, a0x: float, sx: float, a0y: float, sy: float, a1x: float,
               a1y: float, cb: float, sb: float, ca_p: float, sa_p: float, ca_m: float, sa_m: float, mu: float,
               tips_p: bool, tips_m: bool) -> tuple[float, int]:
    """When and how a block resting at ``t0`` [s] leaves rest before ``t1`` on one sample interval:
    (time, EXIT_*), or (inf, EXIT_NONE) if it stays.

    Inside the interval the input is the line a(t) = a0 + slope (t − tl) [m/s², m/s³] — exactly as
    the engines integrate it — and at ``t1`` the next sample (a1x, a1y), the value the next interval
    starts from. The margins are linear in t: the candidate is the earliest root of those positive at
    ``t1``. The tie rule: a margin that is 0 (or negative by rounding) at that root is not an exit;
    the block leaves at the first representable time from there at which :func:`rest_exit` finds a
    positive margin, so the stage it enters accelerates away from rest with the same numbers (θ''/k
    is the uplift margin, the slide's acceleration times slip the slide margin) and cannot fall back
    into rest at the same instant. A time within 2e-12 of the interval's length of ``t1`` is ``t1``.
    """
    ma = rest_margins(a0x + sx * (t0 - tl), a0y + sy * (t0 - tl), cb, sb, ca_p, sa_p, ca_m, sa_m, mu)
    kind = rest_exit(ma[0], ma[1], ma[2], ma[3], ma[4], tips_p, tips_m)
    if kind != EXIT_NONE:
        return t0, kind
    mb = rest_margins(a1x, a1y, cb, sb, ca_p, sa_p, ca_m, sa_m, mu)
    kind_b = rest_exit(mb[0], mb[1], mb[2], mb[3], mb[4], tips_p, tips_m)
    if kind_b == EXIT_NONE:
        return math.inf, EXIT_NONE
    tc = math.inf
    for j in range(5):
        # the margins rest_exit reads: lift-off, each side's uplift where friction tips there, else its slide
        tips = tips_p if j % 2 == 0 else tips_m
        if (j == 4 or (j < 2) == tips) and mb[j] > 0.0:
            tc = min(tc, t0 + (t1 - t0) * ma[j] / (ma[j] - mb[j]))
    t = max(tc, t0)
    snap = 2e-12 * (t1 - tl)
    d = 0.0
    for _ in range(2100):  # doubling steps from one ulp reach t1 well within this
        if t1 - t <= snap:
            break
        m = rest_margins(a0x + sx * (t - tl), a0y + sy * (t - tl), cb, sb, ca_p, sa_p, ca_m, sa_m, mu)
        kind = rest_exit(m[0], m[1], m[2], m[3], m[4], tips_p, tips_m)
        if kind != EXIT_NONE:
            return t, kind
        d = max(2.0 * d, abs(t) * 2.3e-16, 5e-324)
        t += d
    return t1, kind_b


@njit(cache=True)
def leave_rest(kind: int, s: float, slip: float, z: float, r: float, ca: float) -> tuple[int, float, float, float]:
    """The stage a resting block enters through the exit ``kind`` (EXIT_*, not EXIT_NONE):
    (stage, s, slip, z). Lift-off starts a flight from the resting height z = r cos α = h_cg (``ca`` = cos α,
    either corner's ``r`` and ``ca``);
    uplift ± starts rocking on the pivot s = ±1; a slide ± starts sliding with slip = ±1."""
    if kind == EXIT_FLIGHT:
        return ST_FLIGHT, s, slip, r * ca
    if kind in (EXIT_ROCK_PLUS, EXIT_ROCK_MINUS):
        return ST_ROCK, (1.0 if kind == EXIT_ROCK_PLUS else -1.0), slip, z
    return ST_SLIDE, s, (1.0 if kind == EXIT_SLIDE_PLUS else -1.0), z


@njit(cache=True)
def break_instant_chain(stage: int, theta: float, omega: float, v: float, s: float) -> tuple[int, float]:
    """Where a chain of more than ``MAX_INSTANT`` transitions that take no time ends: (stage, s).

    A block that slides (v ≠ 0) keeps sliding (ST_SLIDE returned unchanged: its slide takes time). A
    rotating block (θ or ω not 0) is put on a pivot held for one hold without reaction checks (ST_ROCK:
    the caller sets hold, v = 0); from a flight that pivot is the side it leans (or turns) to. A
    block that does not move rests for one hold (ST_REST: the caller sets v = 0, the rest time, and
    looks for the next exit from rest only after the hold — one step in the fast engine, 1e-9 s in
    the reference). Either way the clock advances: no input makes an engine loop in place.
    ``stage`` is never ST_REST here.
    """
    if stage == ST_FLIGHT:
        if theta != 0.0:
            s = 1.0 if theta > 0.0 else -1.0
        elif omega != 0.0:
            s = 1.0 if omega > 0.0 else -1.0
    if stage == ST_SLIDE and v != 0.0:
        return stage, s
    if theta != 0.0 or omega != 0.0:
        return ST_ROCK, s
    return ST_REST, s


@njit(cache=True)
def enter_stage(stage: int, hold: bool, jam: bool, theta: float, omega: float, v: float, w: float, z: float,
                s: float, slip: float, psi_ref: float, r_ref: float, gx0: float, gz0: float, geo: tuple,
                ig2: float, mu: float
                ) -> tuple[int, float, float, float, float, float, float, float, bool, bool, float, float]:
    """The entry conditions of a stage just entered (transitions that take no time).

    Returns (new stage, theta, omega, v, w, z, s, slip, hold, jam, psi_ref, r_ref); ``new`` = ``stage`` when
    the block stays (the state may still change: ROCK may set ``jam``/``hold``, FLIGHT measures ``z``
    as ζ from the lift-off height from here on and sets ``psi_ref`` = α − |θ| and ``r_ref`` = R of the corner
    sign θ, the lowest, + at θ = 0). ``gx0``/``gz0``: the plate-frame gravity now; ``geo`` the two corners
    (:func:`geometry`).

    * SLIDE: lifts off if gz < 0; with μ > tan α of its leading corner (the corner ``slip``) friction tips
      the block over that corner at once (ROCKSLIDE), or the slide jams (Painlevé: REST);
    * ROCK (not held): :func:`rock_exit` — slides (ROCKSLIDE), flies, sticks (``jam``) or is held;
    * ROCKSLIDE: :func:`rockslide_entry` — lifts off (FLIGHT) or, Painlevé, sticks (ROCK, ``jam``).
    """
    new = stage
    alpha, r, k, _, _ = corner(geo, s)
    if stage == ST_SLIDE:
        a_l, r_l, _, ta_l, _ = corner(geo, slip)  # the leading corner
        if gz0 < 0.0:  # the lift-off margin −gz of REST: at gz = 0 the weightless block slides
            new = ST_FLIGHT
            theta = omega = w = 0.0
            z = geo[1] * geo[4]
        elif friction_tips(mu, ta_l):  # friction tips the sliding block over its leading corner at once
            code = rockslide_entry(0.0, 0.0, v, slip, slip, gx0, gz0, a_l, r_l, ig2, mu)
            if code == 0:
                new, s, theta, omega = ST_ROCKSLIDE, slip, 0.0, 0.0
            elif code == 2:  # Painlevé: the slide jams
                new, v = ST_REST, 0.0
    elif stage == ST_ROCK and not hold:
        code, sl = rock_exit(theta, omega, s, gx0, gz0, alpha, r, ig2, k, mu, jam)
        if code == ROCK_TO_ROCKSLIDE:
            new, slip, v = ST_ROCKSLIDE, sl, 0.0
        elif code == ROCK_TO_FLIGHT:
            new = ST_FLIGHT
            z, v, w = flight_entry(theta, omega, 0.0, s, alpha, r)
        elif code == ROCK_JAM:
            jam = True
        elif code == ROCK_HOLD:
            hold = True
    elif stage == ST_ROCKSLIDE:
        code = rockslide_entry(theta, omega, v, s, slip, gx0, gz0, alpha, r, ig2, mu)
        if code == 1:
            new = ST_FLIGHT
            z, v, w = flight_entry(theta, omega, v, s, alpha, r)
        elif code == 2:
            new, v, jam = ST_ROCK, 0.0, True
    elif stage == ST_FLIGHT:  # from here on z is ζ, measured from the lift-off height
        a_l, r_ref, _, _, _ = corner(geo, -1.0 if theta < 0.0 else 1.0)  # the lowest corner
        psi_ref = a_l - abs(theta)
        z -= r_ref * math.cos(psi_ref)
    return new, theta, omega, v, w, z, s, slip, hold, jam, psi_ref, r_ref


@njit(cache=True)
def after_reaction(theta: float, omega: float, v: float, w: float, z: float, s: float, slip: float, jam: bool,
                   was_sliding: bool, gx: float, gz: float, alpha: float, r: float, ig2: float, k: float,
                   mu: float) -> tuple[int, float, float, float, float, bool, bool]:
    """What a pivot does when ROCK's reactions reach their limit or a sliding pivot stops
    (``was_sliding``, with sign ``slip``): it sticks (ROCK), slides (ROCKSLIDE, the other way when it
    was sliding: on the same way it would slide against its own friction, so it sticks with ``jam``),
    flies (FLIGHT, from its velocity ``v``) or is held for a step (:func:`rock_exit`).

    Returns (stage, v, w, z, slip, jam, hold); v = 0 unless the block flies.
    """
    hold = False
    if was_sliding:
        jam = False
    code, sl = rock_exit(theta, omega, s, gx, gz, alpha, r, ig2, k, mu, jam)
    stage = ST_ROCK
    if code == ROCK_TO_ROCKSLIDE:
        if was_sliding and sl == slip:  # would slide on against its own friction
            jam = True
        else:
            slip, stage = sl, ST_ROCKSLIDE
    elif code == ROCK_TO_FLIGHT:
        z, v, w = flight_entry(theta, omega, v, s, alpha, r)
        stage = ST_FLIGHT
    elif code == ROCK_JAM:
        jam = True
    elif code == ROCK_HOLD:
        hold = True
    if stage != ST_FLIGHT:
        v = 0.0
    return stage, v, w, z, slip, jam, hold
