"""Response spectra: the 5 % damped pseudo-acceleration spectrum of an acceleration history.

A linear single-degree-of-freedom oscillator of natural period T (ω = 2π/T) and damping ratio ζ under the base
acceleration a(t) [any unit]::

    u'' + 2ζω u' + ω² u = −a(t)

(u the displacement relative to the base). Its pseudo-acceleration ``PSA(T) = ω² · max |u|`` is in the unit of a.

**Method** (Nigam & Jennings 1969): between two samples a(t) is taken as linear, and the oscillator's state
(u, u') is advanced by the *exact* solution over the step, ``x[i+1] = A x[i] + B (a[i], a[i+1])`` — no
integration error for a piecewise-linear input, any step. That recurrence is a second-order linear filter from a to
u: with ``A`` and ``B`` as in `nigam_jennings`, ``U(z)/a(z) = (b0 + b1 z⁻¹ + b2 z⁻²)/(1 − tr(A) z⁻¹ + det(A) z⁻²)``
(`filter_coefficients`, ``scipy.signal.lfilter``: `relative_displacement`); the spectrum runs the same recurrence
for all periods at once in a numba kernel. The oscillator starts at rest with a = 0 one step before the first
sample. The input is padded with zeros for one longest period so that a peak of the free vibration after the input
ends counts too.

Verified in ``tests/rig/test_report.py`` against closed forms: the steady-state amplitude under a harmonic input,
``|u| = a0 / sqrt((ω² − Ω²)² + (2ζωΩ)²)``, and the peak of the step response, ``(a0/ω²)(1 + exp(−ζπ/√(1−ζ²)))``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from analysis.compiled_index import njit

DAMPING = 0.05
"""The damping ratio of design spectra [-]."""

DEFAULT_PERIODS: NDArray[np.float64] = np.geomspace(0.02, 5.0, 60)
"""Periods [s] of the report's spectra: 60, logarithmically spaced from 0.02 s to 5 s."""


def nigam_jennings(period: float, dt: float, damping: float = DAMPING) -> tuple[NDArray[np.float64],
                                                                                  NDArray[np.float64]]:
    """The exact one-step matrices (A, B) of the oscillator of ``period`` [s] for a time step ``dt`` [s]:
    ``(u, u')[i+1] = A (u, u')[i] + B (a[i], a[i+1])`` for ``u'' + 2ζω u' + ω² u = −a`` with a linear between
    samples (0 ≤ ζ < 1)."""
    if not (period > 0 and dt > 0 and 0 <= damping < 1):
        raise ValueError(f"period {period!r} s and dt {dt!r} s must be > 0 and damping {damping!r} in [0, 1)")
    w = 2.0 * math.pi / period
    z = damping
    sq = math.sqrt(1.0 - z * z)
    wd = w * sq
    e = math.exp(-z * w * dt)
    s, c = math.sin(wd * dt), math.cos(wd * dt)
    a = np.array([[e * (z / sq * s + c), e * s / wd],
                  [-w / sq * e * s, e * (c - z / sq * s)]])
    k1 = (2 * z * z - 1) / (w * w * dt)
    k2 = 2 * z / (w**3 * dt)
    b11 = e * ((k1 + z / w) * s / wd + (k2 + 1 / w**2) * c) - k2
    b12 = -e * (k1 * s / wd + k2 * c) - 1 / w**2 + k2
    b21 = -(a[0, 0] - 1.0) / (w * w * dt) - a[0, 1]
    b22 = -b21 - a[0, 1]
    return a, np.array([[b11, b12], [b21, b22]])


def filter_coefficients(period: float, dt: float, damping: float = DAMPING) -> tuple[NDArray[np.float64],
                                                                                      NDArray[np.float64]]:
    """(b, a) of the filter from the input a[n] to the relative displacement u[n] (``scipy.signal.lfilter``
    convention), the `nigam_jennings` recurrence written as a transfer function."""
    am, bm = nigam_jennings(period, dt, damping)
    b = np.array([
        bm[0, 1],
        bm[0, 0] - am[1, 1] * bm[0, 1] + am[0, 1] * bm[1, 1],
        -am[1, 1] * bm[0, 0] + am[0, 1] * bm[1, 0],
    ])
    den = np.array([1.0, -(am[0, 0] + am[1, 1]), am[0, 0] * am[1, 1] - am[0, 1] * am[1, 0]])
    return b, den


def relative_displacement(acc: ArrayLike, dt: float, period: float, damping: float = DAMPING) -> NDArray[np.float64]:
    """u[n] of the oscillator of ``period`` [s] under the uniformly sampled base acceleration ``acc`` (step ``dt``
    [s]), at rest before the first sample; unit: that of ``acc`` times s²."""
    b, a = filter_coefficients(period, dt, damping)
    return lfilter(b, a, np.asarray(acc, dtype=float))


@njit(cache=True)
def _peak_displacements(acc: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]
                        ) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """max |u| of every oscillator (one-step matrices ``a[k]``, ``b[k]``, each 2×2) under ``acc``, all run
    together sample by sample (the recurrence of `nigam_jennings`, at rest with a = 0 before the first sample)."""
    m = a.shape[0]
    u = np.zeros(m)
    v = np.zeros(m)
    peak = np.zeros(m)
    prev = 0.0
    for x in acc:
        for k in range(m):
            un = a[k, 0, 0] * u[k] + a[k, 0, 1] * v[k] + b[k, 0, 0] * prev + b[k, 0, 1] * x
            v[k] = a[k, 1, 0] * u[k] + a[k, 1, 1] * v[k] + b[k, 1, 0] * prev + b[k, 1, 1] * x
            u[k] = un
            peak[k] = max(peak[k], abs(un))
        prev = x
    return peak


def pseudo_acceleration_spectrum(acc: ArrayLike, dt: float, periods: ArrayLike = DEFAULT_PERIODS,
                                 damping: float = DAMPING) -> NDArray[np.float64]:
    """``PSA(T) = (2π/T)² max |u|`` for each period T [s] of ``periods`` under ``acc`` sampled every ``dt`` [s],
    in the unit of ``acc`` (module docstring: exact for piecewise-linear input, padded with zeros for one
    longest period). All oscillators advance together in one compiled pass over the samples (the same recurrence
    as `relative_displacement`'s filter, ~5× faster than one filter call per period). NaN samples are not
    allowed; an empty input gives zeros."""
    x = np.asarray(acc, dtype=float).ravel()
    periods = np.asarray(periods, dtype=float).ravel()
    if not np.all(np.isfinite(x)):
        raise ValueError("acceleration samples must be finite")
    if not (dt > 0 and np.all(periods > 0)):
        raise ValueError(f"dt {dt!r} s and every period must be > 0")
    if x.size == 0 or periods.size == 0:
        return np.zeros(periods.size)
    padded = np.concatenate([x, np.zeros(math.ceil(periods.max() / dt) + 1)])
    mats = [nigam_jennings(float(period), dt, damping) for period in periods]
    a = np.array([m[0] for m in mats])
    b = np.array([m[1] for m in mats])
    return (2.0 * math.pi / periods) ** 2 * _peak_displacements(padded, a, b)


def uniform(t: ArrayLike, values: ArrayLike) -> tuple[NDArray[np.float64], float]:
    """Samples ``values`` at times ``t`` [s] on a uniform grid from their first time at the median spacing
    (linear interpolation; non-finite samples dropped): (resampled values, dt [s]). Fewer than 2 samples give an
    empty array and dt = 1."""
    times = np.asarray(t, dtype=float)
    v = np.asarray(values, dtype=float)
    keep = np.isfinite(times) & np.isfinite(v)
    times, v = times[keep], v[keep]
    if times.size < 2:
        return np.zeros(0), 1.0
    order = np.argsort(times, kind="stable")
    times, v = times[order], v[order]
    steps = np.diff(times)
    dt = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0
    if np.allclose(steps, dt, rtol=1e-3, atol=0.0):
        return v, dt
    grid = times[0] + dt * np.arange(math.floor((times[-1] - times[0]) / dt + 1e-9) + 1)
    return np.interp(grid, times, v), dt
