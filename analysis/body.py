"""Rigid rectangular bodies standing on the plate.

Units: metres, kilograms, radians. ``b`` is the full base width along the fall line (plate x), ``h`` the full
height. The centre of mass is at the centroid unless ``b_cg``/``h_cg`` place it elsewhere (the paper's Table V
gives each block's, a few millimetres off the centroid).

**Where the centre of mass is, and which corner each rotation pivots on** (docs/architecture.md §2: +x points
downhill; θ > 0 tips the block towards +x). ``b_cg`` is the centre of mass's distance along +x from the base's
**−x corner** (the uphill corner on a tilted plate); ``h_cg`` its height above the base. So it lies
``d_minus = b_cg`` from the −x corner and ``d_plus = b − b_cg`` from the +x corner, horizontally. A rotation
θ > 0 pivots on the +x corner and is governed by the ``_plus`` quantities, θ < 0 on the −x corner by the
``_minus`` ones:

    α± = atan(d± / h_cg)        the slenderness towards ±x (the angle between the vertical and the line
                                from the ± corner to the centre of mass)
    R± = hypot(d±, h_cg)        the distance from the ± corner to the centre of mass
    I± = m (i_g² + R±²)         the moment of inertia about the ± corner

Turning a block around on the plate (its −x corner becomes its +x corner) is ``b_cg → b − b_cg``
(:meth:`Body.mirrored`): α+ and α− swap. A block whose table reads b_cg from the other corner is entered
mirrored.

**Moment of inertia (an assumption).** A block whose centre of mass is off its centroid is not uniform, and its
moment of inertia about the centre of mass is not known from b, h, b_cg and h_cg. The models take the uniform
block's, i_g² = (b² + h²)/12 about the actual centre of mass. For Table V's blocks (centre of mass ≤ 4 mm off the
centroid in 99–998 mm) any mass distribution that moves it that far changes i_g² by well under 1 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from analysis.errors import AnalysisInputError

G = 9.81
"""Standard gravity used throughout the analysis [m/s²] (as docs/validation.md)."""


@dataclass(frozen=True)
class Body:
    """A rectangular block of base ``b`` and height ``h`` [m], its centre of mass at (``b_cg``, ``h_cg``) [m].

    ``b_cg`` is measured along +x from the base's −x corner, ``h_cg`` up from the base (module docstring); None
    (the default) puts it at the centroid, b/2 or h/2, and the body is then exactly the uniform block the
    models always had. A rotation θ > 0 pivots on the +x corner (the ``*_plus`` properties), θ < 0 on the −x
    corner (``*_minus``). Optional ``depth`` [m] and ``mass`` [kg] are carried for the emulator and session
    logs; the planar models do not depend on them. The moment of inertia about the centre of mass is the uniform
    block's, m (b² + h²)/12, wherever the centre of mass is (an assumption: module docstring).
    """

    b: float
    h: float
    depth: float | None = None
    mass: float | None = None
    name: str = ""
    b_cg: float | None = None
    h_cg: float | None = None

    def __post_init__(self) -> None:
        for field, value in (("b", self.b), ("h", self.h)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise AnalysisInputError(f"Body: {field} must be a finite length > 0 m, got {value!r}")
        for field, given in (("depth", self.depth), ("mass", self.mass)):
            if given is not None and not (math.isfinite(given) and given > 0):
                raise AnalysisInputError(f"Body: {field} must be > 0 when given, got {given!r}")
        for field, offset, side, what in (("b_cg", self.b_cg, "b", "from the base's -x corner along +x"),
                                          ("h_cg", self.h_cg, "h", "above the base")):
            if offset is None:
                continue
            size = getattr(self, side)
            if not (isinstance(offset, int | float) and math.isfinite(offset) and 0 < offset < size):
                raise AnalysisInputError(
                    f"Body: {field} (the centre of mass {what}) must be inside the block, 0 < {field} < "
                    f"{side} = {size!r} m, got {offset!r}")

    # ---------------------------------------------------------------- the centre of mass and each side

    @property
    def cg(self) -> tuple[float, float]:
        """(b_cg, h_cg) [m]: the centre of mass from the base's −x corner along +x, and above the base."""
        return (0.5 * self.b if self.b_cg is None else self.b_cg,
                0.5 * self.h if self.h_cg is None else self.h_cg)

    @property
    def centred(self) -> bool:
        """The centre of mass is at the centroid (b/2, h/2): the uniform block."""
        return self.cg == (0.5 * self.b, 0.5 * self.h)

    @property
    def symmetric(self) -> bool:
        """The two sides are alike (b_cg = b/2): α+ = α−, R+ = R−, one restitution both ways."""
        return self.cg[0] == 0.5 * self.b

    @property
    def d_plus(self) -> float:
        """Horizontal distance from the centre of mass to the +x corner, b − b_cg [m]."""
        return self.b - self.cg[0]

    @property
    def d_minus(self) -> float:
        """Horizontal distance from the centre of mass to the −x corner, b_cg [m]."""
        return self.cg[0]

    # α± and R± as atan2(2d, 2h_cg) and hypot(2d, 2h_cg)/2: mathematically atan2(d, h_cg) and hypot(d, h_cg), and
    # for a centred body bit for bit atan2(b, h) and hypot(b, h)/2 (2·(b − b/2) = b exactly): the models give
    # a centred body exactly the numbers they always gave it

    @property
    def alpha_plus(self) -> float:
        """Slenderness towards +x, atan((b − b_cg)/h_cg) [rad]: θ > 0 pivots on the +x corner."""
        return math.atan2(2.0 * self.d_plus, 2.0 * self.cg[1])

    @property
    def alpha_minus(self) -> float:
        """Slenderness towards −x, atan(b_cg/h_cg) [rad]: θ < 0 pivots on the −x corner."""
        return math.atan2(2.0 * self.d_minus, 2.0 * self.cg[1])

    @property
    def r_plus(self) -> float:
        """Distance from the +x corner to the centre of mass [m]."""
        return 0.5 * math.hypot(2.0 * self.d_plus, 2.0 * self.cg[1])

    @property
    def r_minus(self) -> float:
        """Distance from the −x corner to the centre of mass [m]."""
        return 0.5 * math.hypot(2.0 * self.d_minus, 2.0 * self.cg[1])

    @property
    def p_plus(self) -> float:
        """Frequency parameter rocking on the +x corner, sqrt(m g R+ / I+) [rad/s]."""
        return math.sqrt(G * self.r_plus / (self.i_g**2 + self.r_plus**2))

    @property
    def p_minus(self) -> float:
        """Frequency parameter rocking on the −x corner, sqrt(m g R− / I−) [rad/s]."""
        return math.sqrt(G * self.r_minus / (self.i_g**2 + self.r_minus**2))

    @property
    def k_plus(self) -> float:
        """R+/(i_g² + R+²) [1/m] (= p+²/g): the factor of the rocking equation on the +x corner."""
        return self.r_plus / (self.i_g**2 + self.r_plus**2)

    @property
    def k_minus(self) -> float:
        """R−/(i_g² + R−²) [1/m] (= p−²/g): the factor of the rocking equation on the −x corner."""
        return self.r_minus / (self.i_g**2 + self.r_minus**2)

    def inertia_plus(self) -> float:
        """Moment of inertia about the +x corner, m (i_g² + R+²) [kg m²]; per unit mass [m²] when mass is None."""
        return (1.0 if self.mass is None else self.mass) * (self.i_g**2 + self.r_plus**2)

    def inertia_minus(self) -> float:
        """Moment of inertia about the −x corner, m (i_g² + R−²) [kg m²]; per unit mass [m²] when mass is None."""
        return (1.0 if self.mass is None else self.mass) * (self.i_g**2 + self.r_minus**2)

    def mirrored(self) -> Body:
        """The same block turned around on the plate: its centre of mass b − b_cg from the −x corner (α± swap)."""
        if self.b_cg is None:
            return self
        return replace(self, b_cg=self.b - self.b_cg)

    # ---------------------------------------------------------------- the box (and the centred block)

    @property
    def aspect(self) -> float:
        """b/h [-]."""
        return self.b / self.h

    @property
    def r(self) -> float:
        """Half-diagonal of the box [m]: the distance from a base corner to the centroid (to the centre of mass
        of a centred body; the models use :attr:`r_plus`/:attr:`r_minus`)."""
        return 0.5 * math.hypot(self.b, self.h)

    @property
    def alpha(self) -> float:
        """Slenderness of the box, atan(b/h) [rad] (of a centred body; the models use
        :attr:`alpha_plus`/:attr:`alpha_minus`, which differ from it when the centre of mass is off the
        centroid)."""
        return math.atan2(self.b, self.h)

    @property
    def i_g(self) -> float:
        """Radius of gyration about the centre of mass, sqrt((b² + h²)/12) [m] (the uniform block's, wherever the
        centre of mass is: module docstring)."""
        return math.sqrt((self.b**2 + self.h**2) / 12.0)

    @property
    def p(self) -> float:
        """Frequency parameter of the centred block, sqrt(m g r / I_O) = sqrt(3 g / (4 r)) [rad/s] (the models use
        :attr:`p_plus`/:attr:`p_minus`)."""
        return math.sqrt(G * self.r / (self.i_g**2 + self.r**2))

    # ---------------------------------------------------------------- impacts

    def housner_restitutions(self) -> tuple[float, float]:
        """Housner's angular-velocity ratios ω⁺/ω⁻ at an impact (docs/general-model.md, *Impacts*):
        (e+, e−), e+ for an impact that ends rocking on the +x corner (the block lands on its −x corner),
        e− for one that ends rocking on the −x corner.

        Angular momentum about the corner that lands is conserved (a plastic, sticking impact):
        ω⁺/ω⁻ = (i_g² + h_cg² − d+ d−) / (i_g² + R_new²), R_new the distance from the landing corner to the
        centre of mass. A centred block gives Housner's 1 − 1.5 sin²α both ways (computed as that)."""
        if self.centred:
            e = 1.0 - 1.5 * math.sin(self.alpha) ** 2
            return e, e
        ig2 = self.i_g**2
        num = ig2 + self.cg[1] ** 2 - self.d_plus * self.d_minus
        return num / (ig2 + self.r_minus**2), num / (ig2 + self.r_plus**2)

    def housner_restitution(self) -> float:
        """Housner's angular-velocity ratio at impact, 1 − 1.5 sin²α [-], of a body whose two impacts are alike
        (:attr:`symmetric`). For an off-centre b_cg the ratio depends on the direction: use
        :meth:`housner_restitutions`."""
        e_plus, e_minus = self.housner_restitutions()
        if e_plus != e_minus:
            raise AnalysisInputError(
                f"body {self.label()}: Housner's restitution differs by impact direction (b_cg off the middle): "
                f"{e_plus:.6f} landing on the -x corner, {e_minus:.6f} on the +x corner; use housner_restitutions()")
        return e_plus

    def label(self) -> str:
        """A short label: the name, else ``b x h`` in metres."""
        return self.name or f"{self.b:g}x{self.h:g}"

    @classmethod
    def from_p_alpha(cls, p: float, alpha: float) -> Body:
        """The uniform block with frequency parameter ``p`` [rad/s] and slenderness ``alpha`` [rad]."""
        if not (p > 0 and 0 < alpha < 0.5 * math.pi):
            raise AnalysisInputError(f"Body.from_p_alpha: need p > 0 and 0 < alpha < pi/2, got {p}, {alpha}")
        r = 3.0 * G / (4.0 * p * p)
        return cls(b=2.0 * r * math.sin(alpha), h=2.0 * r * math.cos(alpha))

    @classmethod
    def parse(cls, text: str) -> Body:
        """Parse ``"0.10x0.50"`` (b x h in metres) as given on the command line, optionally with the centre of
        gravity ``"0.099x0.493;cg=0.0515,0.243"`` (b_cg from the base's −x corner, h_cg above the base [m])."""
        size, _, option = text.partition(";")
        parts = size.lower().replace("×", "x").split("x")
        try:
            b, h = (float(v) for v in parts)
        except ValueError:
            raise AnalysisInputError(
                f"body {text!r}: expected BxH in metres, e.g. 0.10x0.50"
            ) from None
        if not option:
            return cls(b=b, h=h)
        name, _, value = option.partition("=")
        try:
            if name.strip() != "cg":
                raise ValueError
            b_cg, h_cg = (float(v) for v in value.split(","))
        except ValueError:
            raise AnalysisInputError(
                f"body {text!r}: expected BxH[;cg=BCG,HCG] in metres, e.g. 0.099x0.493;cg=0.0515,0.243 (the centre "
                "of gravity from the base's -x corner and above the base)"
            ) from None
        return cls(b=b, h=h, b_cg=b_cg, h_cg=h_cg)


TABLE_I: tuple[Body, ...] = tuple(
    Body(b=b, h=h, name=f"T1-{i}")
    for i, (b, h) in enumerate(
        [
            (0.04, 0.20), (0.05, 0.20), (0.06, 0.20),
            (0.10, 0.50), (0.13, 0.50), (0.15, 0.50), (0.18, 0.50),
            (0.20, 1.00), (0.25, 1.00), (0.30, 1.00),
            (0.30, 1.50), (0.38, 1.50),
        ],
        start=1,
    )
)
"""The 12 bodies of the paper's analytical study (Table I)."""

TABLE_V: tuple[Body, ...] = tuple(
    Body(b=b / 1000, h=h / 1000, depth=d / 1000, mass=m, name=f"T5-{i}", b_cg=b_cg / 1000, h_cg=h_cg / 1000)
    for i, (b, h, d, m, b_cg, h_cg) in enumerate(
        [
            (99, 493, 201.2, 5.22, 51.5, 243), (130, 500, 305, 13.11, 65, 254),
            (152, 500, 301.5, 15.31, 76.5, 251.5), (39, 200, 81, 0.36, 19.5, 100), (49, 200, 109, 0.56, 25, 100),
            (200, 998, 410, 54.96, 100, 495), (248, 995, 490, 65.14, 124, 499),
        ],
        start=1,
    )
)
"""The seven bodies of the paper's shake-table campaign (Table V): base, height, depth [mm → m], mass [kg] and the
centre of gravity (b_cg, h_cg) as printed. The paper does not say which base corner b_cg is measured from; here it
is the −x corner (the uphill one on the tilted plate), the convention of :class:`Body`: body 1's centre of mass is
then 47.5 mm from its downhill corner (α+ = 11.06°) and 51.5 mm from its uphill one (α− = 11.97°), and body 5's
24 mm and 25 mm. A lab that mounts a block the other way round uses ``Body.mirrored()`` (in a sequence file, gives
``b_cg`` itself). Bodies 2, 4, 6 and 7 have b_cg = b/2: alike both ways; 4 is centred altogether."""
