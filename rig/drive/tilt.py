"""The static tilt β as a smooth, jerk-limited ramp (docs/architecture.md §2: tilt = pitch = +β, +x downhill).

The ramp is the table's quintic move (`analysis.table.moves`) ``θ(τ) = θ0 + (θ1 - θ0)(10τ³ - 15τ⁴ + 6τ⁵)``,
``τ = t / T``: angle, rate and angular acceleration are continuous (zero at both ends), and the jerk is bounded;
`ramp_duration` picks the shortest T that keeps its peaks inside the table's tilt limits.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.table.model import TiltLimits
from analysis.table.moves import quintic, shortest_duration


def ramp_duration(change: float, limits: TiltLimits, rate: float) -> float:
    """Shortest ramp [s] for an angle change [rad] inside ``limits``, rounded up to whole samples at ``rate``."""
    change = abs(change)
    if change == 0.0:
        return 0.0
    shortest = shortest_duration(change, limits.rate, limits.acceleration, limits.jerk)
    return math.ceil(shortest * rate) / rate


def ramp(start: float, end: float, duration: float, rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angle [rad], rate [rad/s] and angular acceleration [rad/s²] of the ramp, sampled at ``rate`` [Hz].

    ``round(duration · rate)`` samples at ``t = k / rate``; the sample at ``t = duration`` (the end value)
    belongs to what follows, so ramps and holds concatenate without a repeated instant.
    """
    n = round(duration * rate)
    if n == 0:
        return np.empty(0), np.empty(0), np.empty(0)
    tau = np.arange(n) / n
    change = end - start
    angle = start + change * np.asarray(quintic(tau))
    speed = change * 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
    accel = change * 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / duration**2
    return angle, speed, accel
