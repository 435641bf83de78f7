"""The static tilt β as a smooth, jerk-limited ramp (ARCHITECTURE §2: tilt = pitch = +β, +x downhill).

The ramp is the quintic ``θ(τ) = θ0 + (θ1 - θ0)(10τ³ - 15τ⁴ + 6τ⁵)``, ``τ = t / T``: angle, rate and
angular acceleration are continuous (zero at both ends), and the jerk is bounded. For a change Δ = |θ1 - θ0|
its peaks are

* rate ``15/8 · Δ / T``, at τ = 1/2;
* angular acceleration ``10/√3 · Δ / T²``, at τ = 1/2 ∓ √3/6;
* jerk ``60 · Δ / T³``, at τ = 0 and 1;

so `ramp_duration` picks the shortest T that keeps all three inside the table's tilt limits.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.table_model import TiltLimits

_RATE_PEAK = 15.0 / 8.0
_ACCELERATION_PEAK = 10.0 / math.sqrt(3.0)
_JERK_PEAK = 60.0


def ramp_duration(change: float, limits: TiltLimits, rate: float) -> float:
    """Shortest ramp [s] for an angle change [rad] inside ``limits``, rounded up to whole samples at ``rate``."""
    change = abs(change)
    if change == 0.0:
        return 0.0
    shortest = max(
        _RATE_PEAK * change / limits.rate,
        math.sqrt(_ACCELERATION_PEAK * change / limits.acceleration),
        (_JERK_PEAK * change / limits.jerk) ** (1.0 / 3.0),
    )
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
    angle = start + change * tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    speed = change * 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
    accel = change * 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / duration**2
    return angle, speed, accel
