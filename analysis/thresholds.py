"""Eq. 1: the plate acceleration that starts rocking, towards either side of an inclined plate.

Conventions (docs/architecture.md §2): +x points downhill, β > 0 is the inclination, accelerations are
horizontal/vertical ground accelerations in m/s² (or any unit, consistently with ``g``).
A body resting on the plate starts to rock **towards +x (downhill)** when the ground accelerates
*uphill* by more than ``a_plus`` (a_x < −a_plus), and **towards −x (uphill)** when it accelerates
downhill by more than ``a_minus`` (a_x > a_minus):

    a_plus  = (g + a_y) · tan(α+ − β) = (g + a_y)(tan α+ − tan β)/(1 + tan α+ tan β)   (paper Eq. 1)
    a_minus = (g + a_y) · tan(α− + β)

α± is the slenderness towards each side (``analysis.body``: atan of the centre of mass's horizontal distance to
that corner over its height; both atan(b/h) for a centred block, and then tan α+ = b/h as the paper writes it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from analysis.body import Body, G


def uplift_thresholds(
    body: Body, beta: float, acc_v: ArrayLike = 0.0, g: float = G
) -> tuple[np.ndarray, np.ndarray]:
    """Return (a_plus, a_minus): horizontal accelerations [same unit as g] that start rocking towards +x
    (the ground accelerating uphill, −x, by a_plus) and towards −x (downhill by a_minus).

    ``acc_v`` is the upward vertical ground acceleration (scalar or array), same unit as ``g``.
    """
    gv = g + np.asarray(acc_v, dtype=float)
    return gv * np.tan(body.alpha_plus - beta), gv * np.tan(body.alpha_minus + beta)


def exceeds_threshold(
    body: Body, beta: float, acc_h: np.ndarray, acc_v: np.ndarray | None = None, g: float = G
) -> bool:
    """True when the record ever reaches Eq. 1 in either direction (the pre-screen).

    ``acc_h``/``acc_v`` in the unit of ``g``. A record that never does leaves the body at rest.
    """
    a_plus, a_minus = uplift_thresholds(body, beta, 0.0 if acc_v is None else acc_v, g)
    acc_h = np.asarray(acc_h, dtype=float)
    return bool(np.any(-acc_h >= a_plus) or np.any(acc_h >= a_minus))
