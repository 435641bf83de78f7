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
"""

from __future__ import annotations

import math

from numba import njit

from analysis.equations import (
    pivot_reactions,
    plate_gravity,
    rocking_acceleration,
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
    """θ' after a plastic, sticking landing on the corner s = sign θ (angular momentum about it)."""
    s = 1.0 if theta > 0.0 else -1.0
    psi = alpha - abs(theta)
    dx = -s * r * math.sin(psi)
    dz = r * math.cos(psi)
    wz = (ig2 * (-omega) + dx * w - dz * v) / (ig2 + r * r)
    return -wz


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
    add = rocking_acceleration(theta, s, gx, gz, alpha, k)
    rt, rn = pivot_reactions(theta, omega, add, s, gx, gz, alpha, r)
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
def rest_margins(ax_: float, ay_: float, cb: float, sb: float, ca: float, sa: float, mu: float
                 ) -> tuple[float, float, float, float, float]:
    """The five REST margins (> 0: that exit is reached): uplift +/− (Eq. 1 times cos α, written as
    the rocking equation's θ'' at θ = 0 over k, so that a positive margin always starts a rotation —
    the tan α form can be positive by rounding while θ'' is 0), slide +/−, lift-off (−gz)."""
    gx, gz = plate_gravity(ax_, ay_, cb, sb)
    return gx * ca - gz * sa, -gx * ca - gz * sa, gx - mu * gz, -gx - mu * gz, -gz


@njit(cache=True, inline="always")
def rest_exit(m1: float, m2: float, m3: float, m4: float, m5: float, slide_first: bool) -> int:
    """The exit among the positive margins (priority: lift-off, then rock or slide)."""
    if m5 > 0.0:
        return EXIT_FLIGHT
    rock = EXIT_ROCK_PLUS if m1 > 0.0 else (EXIT_ROCK_MINUS if m2 > 0.0 else EXIT_NONE)
    slide = EXIT_SLIDE_PLUS if m3 > 0.0 else (EXIT_SLIDE_MINUS if m4 > 0.0 else EXIT_NONE)
    if rock != EXIT_NONE and (slide == EXIT_NONE or not slide_first):
        return rock
    return slide


@njit(cache=True)
def leave_rest(kind: int, s: float, slip: float, z: float, r: float, ca: float) -> tuple[int, float, float, float]:
    """The stage a resting block enters through the exit ``kind`` (EXIT_*, not EXIT_NONE):
    (stage, s, slip, z). Lift-off starts a flight from the resting height z = r cos α (``ca`` = cos α);
    uplift ± starts rocking on the pivot s = ±1; a slide ± starts sliding with slip = ±1."""
    if kind == EXIT_FLIGHT:
        return ST_FLIGHT, s, slip, r * ca
    if kind in (EXIT_ROCK_PLUS, EXIT_ROCK_MINUS):
        return ST_ROCK, (1.0 if kind == EXIT_ROCK_PLUS else -1.0), slip, z
    return ST_SLIDE, s, (1.0 if kind == EXIT_SLIDE_PLUS else -1.0), z


@njit(cache=True)
def break_instant_chain(stage: int, theta: float, omega: float, s: float) -> tuple[int, float]:
    """Where a chain of more than ``MAX_INSTANT`` transitions that take no time ends: (stage, s).

    A sliding block keeps sliding (ST_SLIDE returned unchanged). A moving block (θ or ω not 0) is
    put on a pivot held for one step without reaction checks (ST_ROCK: the caller sets hold, v = 0);
    from a flight that pivot is the side it leans (or turns) to. A block that does not move rests
    (ST_REST: the caller sets v = 0 and the rest time). ``stage`` is never ST_REST here.
    """
    if stage == ST_FLIGHT:
        if theta != 0.0:
            s = 1.0 if theta > 0.0 else -1.0
        elif omega != 0.0:
            s = 1.0 if omega > 0.0 else -1.0
    if stage == ST_SLIDE:
        return stage, s
    if theta != 0.0 or omega != 0.0:
        return ST_ROCK, s
    return ST_REST, s


@njit(cache=True)
def enter_stage(stage: int, hold: bool, jam: bool, theta: float, omega: float, v: float, w: float, z: float,
                s: float, slip: float, psi_ref: float, gx0: float, gz0: float, alpha: float, r: float,
                ig2: float, k: float, mu: float, ta: float, ca: float
                ) -> tuple[int, float, float, float, float, float, float, float, bool, bool, float]:
    """The entry conditions of a stage just entered (transitions that take no time).

    Returns (new stage, theta, omega, v, w, z, s, slip, hold, jam, psi_ref); ``new`` = ``stage`` when
    the block stays (the state may still change: ROCK may set ``jam``/``hold``, FLIGHT measures ``z``
    as ζ from the lift-off height from here on and sets ``psi_ref`` = α − |θ|). ``gx0``/``gz0``: the
    plate-frame gravity now; ``ta`` = tan α, ``ca`` = cos α, ``k`` = r/(i_g² + r²).

    * SLIDE: lifts off if gz ≤ 0; with μ > tan α friction tips the block over its leading corner at
      once (ROCKSLIDE), or the slide jams (Painlevé: REST);
    * ROCK (not held): :func:`rock_exit` — slides (ROCKSLIDE), flies, sticks (``jam``) or is held;
    * ROCKSLIDE: :func:`rockslide_entry` — lifts off (FLIGHT) or, Painlevé, sticks (ROCK, ``jam``).
    """
    new = stage
    if stage == ST_SLIDE:
        if gz0 <= 0.0:
            new = ST_FLIGHT
            theta = omega = w = 0.0
            z = r * ca
        elif mu > ta:  # friction tips the sliding block over its leading corner at once
            code = rockslide_entry(0.0, 0.0, v, slip, slip, gx0, gz0, alpha, r, ig2, mu)
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
        psi_ref = alpha - abs(theta)
        z -= r * math.cos(psi_ref)
    return new, theta, omega, v, w, z, s, slip, hold, jam, psi_ref


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
