"""Rigid rectangular bodies standing on the plate.

Units: metres, kilograms, radians. ``b`` is the full base width along the fall line (plate x),
``h`` the full height; the centre of mass is at the centroid (uniform body, as in the paper).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from analysis.errors import AnalysisInputError

G = 9.81
"""Standard gravity used throughout the analysis [m/s²] (as docs/validation.md)."""


@dataclass(frozen=True)
class Body:
    """A uniform rectangular block of base ``b`` and height ``h`` [m].

    Optional ``depth`` [m] and ``mass`` [kg] are carried for the emulator and session logs; the
    planar models do not depend on them.
    """

    b: float
    h: float
    depth: float | None = None
    mass: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        for field, value in (("b", self.b), ("h", self.h)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise AnalysisInputError(f"Body: {field} must be a finite length > 0 m, got {value!r}")
        for field, value in (("depth", self.depth), ("mass", self.mass)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise AnalysisInputError(f"Body: {field} must be > 0 when given, got {value!r}")

    @property
    def aspect(self) -> float:
        """b/h [-]."""
        return self.b / self.h

    @property
    def r(self) -> float:
        """Half-diagonal: distance from a base corner to the centre of mass [m]."""
        return 0.5 * math.hypot(self.b, self.h)

    @property
    def alpha(self) -> float:
        """Slenderness angle atan(b/h) [rad]."""
        return math.atan2(self.b, self.h)

    @property
    def i_g(self) -> float:
        """Radius of gyration about the centre of mass, sqrt((b² + h²)/12) [m]."""
        return math.sqrt((self.b**2 + self.h**2) / 12.0)

    @property
    def p(self) -> float:
        """Frequency parameter sqrt(m g r / I_O) = sqrt(3 g / (4 r)) [rad/s]."""
        return math.sqrt(G * self.r / (self.i_g**2 + self.r**2))

    def housner_restitution(self) -> float:
        """Housner's angular-velocity ratio at impact, 1 − 1.5 sin²α [-]."""
        return 1.0 - 1.5 * math.sin(self.alpha) ** 2

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
        """Parse ``"0.10x0.50"`` (b x h in metres) as given on the command line."""
        parts = text.lower().replace("×", "x").split("x")
        try:
            b, h = (float(v) for v in parts)
        except ValueError:
            raise AnalysisInputError(
                f"body {text!r}: expected BxH in metres, e.g. 0.10x0.50"
            ) from None
        return cls(b=b, h=h)


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
    Body(b=b / 1000, h=h / 1000, depth=d / 1000, mass=m, name=f"T5-{i}")
    for i, (b, h, d, m) in enumerate(
        [
            (99, 493, 201.2, 5.22), (130, 500, 305, 13.11), (152, 500, 301.5, 15.31),
            (39, 200, 81, 0.36), (49, 200, 109, 0.56), (200, 998, 410, 54.96), (248, 995, 490, 65.14),
        ],
        start=1,
    )
)
"""The seven bodies of the paper's shake-table campaign (Table V)."""
