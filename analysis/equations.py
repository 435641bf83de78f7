"""The equations of motion of a rigid block on an inclined, moving plate (paper Eqs. 1–10).

Everything here is a compiled scalar function shared by the reference solver and the fast engine,
so that the two differ only in how they integrate and locate events.

Conventions (docs/architecture.md §2). Plate frame: x along the fall line, **+x downhill**, z normal to the
plate, up; β > 0 is the inclination. Ground (table) accelerations ``ax`` (horizontal, positive
towards the downhill side) and ``ay`` (vertical, positive up) are in m/s². θ is the rotation of the
block relative to the plate: **θ > 0 tips the block towards +x** (rocking on its downhill corner),
θ < 0 on its uphill corner. ``s`` is the pivot side (+1 downhill corner, −1 uphill corner).

A block whose centre of mass is off its centroid (``analysis.body``: b_cg, h_cg) has a slenderness α± and a
distance R± from each corner to the centre of mass: every function below that takes a pivot ``s`` takes that
pivot's α and r (or k = r/(i_g² + r²)); the callers pass α+, R+ for s = +1 and α−, R− for s = −1.

In the plate frame the block feels the effective gravity (per unit mass)::

    gx = −ax cos β + (g + ay) sin β     along +x (downhill)
    gz =  ax sin β + (g + ay) cos β     into the plate (the normal reaction at rest, Eq. 3)

and the block then behaves as on a level plate under (gx, −gz). With ψ = α − s·θ (= α − |θ| on
the pivot's own side; the functions below use s·θ so that they continue smoothly through θ = 0,
which keeps an integration step that crosses an impact at full order while the impact is located):

    θ'' = r/(i_g² + r²) · (gx cos ψ − s gz sin ψ)                    (Eq. 2 / Eq. 6)

The paper writes Eq. 2 with the opposite sign of β (its x axis points uphill); with β → −β the two
agree term by term. Uplift from rest towards +x needs gx > gz tan α+, i.e. −ax > (g + ay) tan(α+ − β),
and towards −x −gx > gz tan α−, i.e. ax > (g + ay) tan(α− + β): Eq. 1 (α+ = α− = α for a centred block).
"""

from __future__ import annotations

import math

from analysis.compiled_index import njit

G = 9.81


@njit(cache=True, inline="always")
def plate_gravity(ax: float, ay: float, cb: float, sb: float) -> tuple[float, float]:
    """Effective gravity in the plate frame (gx along +x, gz into the plate) [m/s²]."""
    gv = G + ay
    return -ax * cb + gv * sb, ax * sb + gv * cb


@njit(cache=True, inline="always")
def rocking_acceleration(theta: float, s: float, gx: float, gz: float, alpha: float, k: float) -> float:
    """θ'' [rad/s²] of a block rocking on pivot ``s``; ``k`` = r/(i_g² + r²) [1/m] (= p²/g uniform)."""
    psi = alpha - s * theta
    return rocking_acceleration_cs(s, gx, gz, math.cos(psi), math.sin(psi), k)


@njit(cache=True, inline="always")
def rocking_acceleration_cs(s: float, gx: float, gz: float, c: float, sn: float, k: float) -> float:
    """``rocking_acceleration`` from c, sn = cos ψ, sin ψ of the state (ψ = α − s θ) [rad/s²]: Eq. 2 as the
    engines that carry cos ψ and sin ψ from step to step take it."""
    return k * (gx * c - s * gz * sn)


@njit(cache=True, inline="always")
def rocking_acceleration_linear(
    theta: float, s: float, gx: float, gz: float, alpha: float, k: float
) -> float:
    """Linearised θ'' (cos ψ ≈ 1, sin ψ ≈ ψ): Housner's linear model, uplift at α·g on a level plate."""
    return k * (gx - gz * (s * alpha - theta))


@njit(cache=True, inline="always")
def uplift_margins(gx: float, gz: float, tan_plus: float, tan_minus: float) -> tuple[float, float]:
    """(m+, m−): positive when the resting block starts rocking towards +x, resp. −x (Eq. 1); ``tan_plus``,
    ``tan_minus`` = tan α± (the slenderness towards each side, ``analysis.body``)."""
    return gx - gz * tan_plus, -gx - gz * tan_minus


@njit(cache=True, inline="always")
def pivot_reactions(
    theta: float, omega: float, alpha_dd: float, s: float, gx: float, gz: float, alpha: float, r: float
) -> tuple[float, float]:
    """Reactions per unit mass at a pivot that does not slip (R_t along +x, R_n normal) [m/s²].

    From Newton's law for the centre of mass, which sits at r·(−s sin ψ, cos ψ) from the pivot.
    The block leaves the plate when R_n < 0 (jump) and the pivot slips when |R_t| > μ R_n.
    """
    psi = alpha - s * theta
    return pivot_reactions_cs(omega, alpha_dd, s, gx, gz, math.cos(psi), math.sin(psi), r)


@njit(cache=True, inline="always")
def pivot_reactions_cs(
    omega: float, alpha_dd: float, s: float, gx: float, gz: float, c: float, sn: float, r: float
) -> tuple[float, float]:
    """``pivot_reactions`` from c, sn = cos ψ, sin ψ of the state (ψ = α − s θ) [m/s²]."""
    rt = r * c * alpha_dd + s * r * sn * omega * omega - gx
    rn = gz + s * r * sn * alpha_dd - r * c * omega * omega
    return rt, rn


@njit(cache=True, inline="always")
def rocking_sliding_acceleration(
    theta: float, omega: float, s: float, slip: float, gx: float, gz: float,
    alpha: float, r: float, ig2: float, mu: float,
) -> tuple[float, float, float]:
    """Rotation with sliding (Eqs. 9–10): (θ'', pivot acceleration along +x, R_n).

    ``slip`` is the sign of the pivot's sliding velocity (Coulomb friction R_t = −μ·slip·R_n).
    """
    psi = alpha - s * theta
    c = math.cos(psi)
    sn = math.sin(psi)
    q = sn - mu * s * slip * c
    theta_dd = s * r * q * (r * c * omega * omega - gz) / (ig2 + r * r * sn * q)
    rn = gz + s * r * sn * theta_dd - r * c * omega * omega
    rt = -mu * slip * rn
    x_dd = gx + rt - (r * c * theta_dd + s * r * sn * omega * omega)
    return theta_dd, x_dd, rn


@njit(cache=True, inline="always")
def sliding_acceleration(slip: float, gx: float, gz: float, mu: float) -> float:
    """Pure sliding (Eq. 5): acceleration of the block along +x relative to the plate [m/s²]."""
    return gx - mu * slip * gz
