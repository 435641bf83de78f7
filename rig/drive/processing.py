"""Record processing for the table: baseline, zero-phase high-pass, integration, end correction, resampling.

Every function works on one evenly sampled channel in SI units (acceleration m/s², velocity m/s,
displacement m, time step s) and is linear in the acceleration, so a scale factor may be applied before or
after processing with the same result.

The chain (`process_channel`), after Boore (2005, "On pads and filters: processing strong-motion data",
BSSA 95(2)) for acausal filtering:

1. **baseline**: subtract the least-squares polynomial (default degree 1) of the acceleration, which
   removes an offset and a linear drift of the sensor's zero;
2. **taper**: a half-cosine over the first and last ``taper`` seconds so the record starts and ends at
   zero acceleration;
3. **pad**: zeros of ``0.75 · order / fc`` seconds on each side (Boore's total pad 1.5 n / fc), long enough
   for the zero-phase filter's transients, which are kept — they are part of the filtered motion;
4. **high-pass**: Butterworth of ``order`` at the corner ``fc`` applied forward and backward
   (`scipy.signal.sosfiltfilt`): zero phase, magnitude response squared;
5. **integration** to velocity and displacement (trapezoid, from rest);
6. **end correction**: the quintic polynomial that matches the residual displacement, velocity and
   acceleration at both ends is subtracted (from displacement; its derivatives from velocity and
   acceleration), so the table starts and ends at rest at home. After the pads this correction is small;
   `ProcessedChannel.correction_peak` reports its largest acceleration.

`trim_pads` then cuts the parts of the pads where every channel's acceleration, velocity and displacement
stay below a fraction of their peaks (the filter's transients have died out) and corrects the new ends
again, so a low corner does not add minutes of standing still to a drive.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy import integrate, signal

#: Default Butterworth order of the high-pass (applied twice by the zero-phase filter).
FILTER_ORDER = 4
#: Default degree of the baseline polynomial removed from the acceleration.
BASELINE_DEGREE = 1
#: Default length of the half-cosine taper at each end of a record [s].
TAPER_SECONDS = 1.0


@dataclass(frozen=True)
class ProcessedChannel:
    """One channel after `process_channel`, sampled at the input's ``dt`` and padded on both sides.

    Attributes:
        acceleration: m/s², consistent with ``velocity`` and ``displacement`` (starts and ends at rest).
        velocity: m/s.
        displacement: m.
        pad: samples of padding before the record's first sample (the record starts at ``pad * dt``).
        correction_peak: largest |acceleration| of the end correction [m/s²].
    """

    acceleration: np.ndarray
    velocity: np.ndarray
    displacement: np.ndarray
    pad: int
    correction_peak: float


def remove_baseline(acc: np.ndarray, degree: int = BASELINE_DEGREE) -> np.ndarray:
    """``acc`` minus its least-squares polynomial of ``degree`` in time (degree -1 returns a copy)."""
    acc = np.asarray(acc, dtype=np.float64)
    if degree < 0:
        return acc.copy()
    if acc.size <= degree:
        return acc - acc.mean()
    x = np.linspace(-1.0, 1.0, acc.size)  # scaled time: a well-conditioned fit at any length
    fit = np.polynomial.Polynomial.fit(x, acc, degree, domain=[-1.0, 1.0])
    return acc - fit(x)


def taper_ends(acc: np.ndarray, dt: float, seconds: float = TAPER_SECONDS) -> np.ndarray:
    """``acc`` with a half-cosine ramp from 0 over the first and last ``seconds`` (at most a quarter each)."""
    out = np.array(acc, dtype=np.float64)
    n = min(round(seconds / dt), out.size // 4)
    if n >= 1:
        ramp = 0.5 * (1.0 - np.cos(np.pi * (np.arange(n) + 0.5) / n))
        out[:n] *= ramp
        out[-n:] *= ramp[::-1]
    return out


def pad_samples(fc: float, dt: float, order: int = FILTER_ORDER) -> int:
    """Zeros on each side for a zero-phase high-pass at ``fc`` [Hz]: ``0.75 · order / fc`` seconds."""
    return math.ceil(0.75 * order / fc / dt)


def highpass(acc: np.ndarray, dt: float, fc: float, order: int = FILTER_ORDER) -> np.ndarray:
    """Zero-phase Butterworth high-pass of ``order`` at corner ``fc`` [Hz] (no padding of its own)."""
    nyquist = 0.5 / dt
    if not 0.0 < fc < nyquist:
        raise ValueError(f"corner frequency {fc:g} Hz must lie in (0, {nyquist:g}) Hz for dt = {dt:g} s")
    return signal.sosfiltfilt(_butter_highpass(order, fc, 1.0 / dt), acc, padtype=None)


@functools.lru_cache(maxsize=256)
def _butter_highpass(order: int, fc: float, fs: float) -> np.ndarray:
    """Second-order sections of the Butterworth high-pass (cached: a study reuses a few corners)."""
    return signal.butter(order, fc, btype="highpass", fs=fs, output="sos")


def integrate_from_rest(acc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement from rest at the first sample (cumulative trapezoid)."""
    vel = integrate.cumulative_trapezoid(acc, dx=dt, initial=0.0)
    disp = integrate.cumulative_trapezoid(vel, dx=dt, initial=0.0)
    return vel, disp


def end_correction(n: int, dt: float, start: tuple[float, float, float], end: tuple[float, float, float]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quintic with given (displacement, velocity, acceleration) at the first and last sample.

    Returns its displacement, velocity and acceleration on the ``n`` samples (SI units).
    """
    duration = (n - 1) * dt
    if duration <= 0.0:
        zero = np.zeros(n)
        return zero, zero.copy(), zero.copy()
    # In τ = t / T: p(τ) = Σ c_k τ^k, dp/dt = p'(τ) / T, d²p/dt² = p''(τ) / T².
    d0, v0, a0 = start
    d1, v1, a1 = end
    lhs = np.array([
        [1, 0, 0, 0, 0, 0],
        [0, 1, 0, 0, 0, 0],
        [0, 0, 2, 0, 0, 0],
        [1, 1, 1, 1, 1, 1],
        [0, 1, 2, 3, 4, 5],
        [0, 0, 2, 6, 12, 20],
    ], dtype=np.float64)
    rhs = np.array([d0, v0 * duration, a0 * duration**2, d1, v1 * duration, a1 * duration**2])
    coefficients = np.linalg.solve(lhs, rhs)
    tau = np.linspace(0.0, 1.0, n)
    degrees = np.arange(6)
    return (
        _horner(coefficients, tau),
        _horner(coefficients[1:] * degrees[1:], tau) / duration,
        _horner(coefficients[2:] * degrees[2:] * degrees[1:-1], tau) / duration**2,
    )


def _horner(coefficients: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``Σ c_k x^k`` by Horner's rule, in place (one array for any degree)."""
    out = np.full(x.shape, coefficients[-1])
    for c in coefficients[-2::-1]:
        out *= x
        out += c
    return out


def process_channel(acc: np.ndarray, dt: float, fc: float, *, order: int = FILTER_ORDER,
                    baseline_degree: int = BASELINE_DEGREE, taper: float = TAPER_SECONDS,
                    pad: int | None = None) -> ProcessedChannel:
    """The whole chain of the module docstring for one acceleration channel [m/s²] at corner ``fc`` [Hz].

    ``pad`` (samples per side) defaults to `pad_samples`; pass a common value to keep several channels of
    one record aligned.
    """
    pad = pad_samples(fc, dt, order) if pad is None else pad
    core = taper_ends(remove_baseline(acc, baseline_degree), dt, taper)
    padded = np.concatenate([np.zeros(pad), core, np.zeros(pad)])
    filtered = highpass(padded, dt, fc, order)
    vel, disp = integrate_from_rest(filtered, dt)
    acc_c, vel_c, disp_c, correction_peak = _corrected(filtered, vel, disp, dt)
    return ProcessedChannel(acc_c, vel_c, disp_c, pad, correction_peak)


def _corrected(acc: np.ndarray, vel: np.ndarray, disp: np.ndarray, dt: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The three signals minus the `end_correction` that brings both ends to rest, and its peak [m/s²]."""
    p, dp, ddp = end_correction(acc.size, dt, (disp[0], vel[0], acc[0]), (disp[-1], vel[-1], acc[-1]))
    return acc - ddp, vel - dp, disp - p, float(np.max(np.abs(ddp)))


def trim_pads(channels: dict[str, ProcessedChannel], dt: float, record_samples: int, *, rtol: float = 1e-2,
              margin: float = 0.5) -> dict[str, ProcessedChannel]:
    """The channels (aligned, same pad) without the quiet parts of their pads.

    A pad sample is quiet when, in every channel, |acceleration|, |velocity| and |displacement| are all
    below ``rtol`` times that channel's peaks; ``margin`` seconds of quiet are kept at each end. The record's
    own samples are always kept. The new ends are brought to rest again (`end_correction`).
    """
    first = next(iter(channels.values()))
    pad, n = first.pad, first.acceleration.size
    loud = np.zeros(n, dtype=bool)
    for ch in channels.values():
        for values in (ch.acceleration, ch.velocity, ch.displacement):
            peak = np.max(np.abs(values))
            if peak > 0.0:
                loud |= np.abs(values) > rtol * peak
    loud[pad:pad + record_samples] = True
    keep = round(margin / dt)
    start = max(0, int(np.argmax(loud)) - keep)
    stop = min(n, n - int(np.argmax(loud[::-1])) + keep)
    out = {}
    for axis, ch in channels.items():
        acc, vel, disp, peak = _corrected(
            ch.acceleration[start:stop], ch.velocity[start:stop], ch.displacement[start:stop], dt
        )
        out[axis] = ProcessedChannel(acc, vel, disp, pad - start, max(peak, ch.correction_peak))
    return out


#: Largest relative difference between ``rate · dt`` and the resampling ratio: the drive's time base may be
#: stretched by at most 1 µs a second (a 120 Hz record whose file writes dt = 0.00833333 s plays at 25/3).
RATIO_TOLERANCE = 1e-6
#: Largest denominator of the resampling ratio (it sets the length of the polyphase filter).
MAX_DENOMINATOR = 1000


@functools.lru_cache(maxsize=256)
def resample_ratio(dt: float, rate: float) -> tuple[int, int]:
    """``(up, down)``: the fraction with the smallest ``down`` ≤ `MAX_DENOMINATOR` whose value differs from
    ``rate · dt`` by at most `RATIO_TOLERANCE` (relative)."""
    target = rate * dt
    if not (math.isfinite(target) and target > 0):
        raise ValueError(f"cannot resample dt = {dt!r} s to {rate:g} Hz: rate · dt must be finite and > 0")
    exact = Fraction(target)
    for down in range(1, MAX_DENOMINATOR + 1):
        ratio = exact.limit_denominator(down)
        if ratio > 0 and abs(float(ratio) - target) <= RATIO_TOLERANCE * target:
            return ratio.numerator, ratio.denominator
    raise ValueError(
        f"cannot resample dt = {dt!r} s to {rate:g} Hz: {target!r} is within {RATIO_TOLERANCE:g} of no ratio "
        f"of whole numbers with a denominator up to {MAX_DENOMINATOR} (check the record's dt)"
    )


#: Anti-aliasing / anti-imaging low-pass: flat to 80 % of the lower Nyquist frequency, 80 dB down at it.
_PASSBAND = 0.8
_STOPBAND_DB = 80.0


@functools.lru_cache(maxsize=64)
def _lowpass_taps(up: int, down: int) -> np.ndarray:
    """Kaiser-window FIR for `scipy.signal.resample_poly` (cut-off relative to the upsampled rate)."""
    nyquist_fraction = 1.0 / max(up, down)  # the lower Nyquist frequency, as a fraction of the upsampled one
    width = (1.0 - _PASSBAND) * nyquist_fraction
    numtaps, beta = signal.kaiserord(_STOPBAND_DB, width)
    numtaps |= 1  # odd: a symmetric filter with an integer delay
    return signal.firwin(numtaps, (1.0 + _PASSBAND) / 2.0 * nyquist_fraction, window=("kaiser", beta))


def resample(values: np.ndarray, dt: float, rate: float) -> np.ndarray:
    """``values`` sampled every ``dt`` [s] resampled to ``rate`` [Hz] without aliasing.

    A polyphase FIR (`scipy.signal.resample_poly`) low-passes at the lower of the two Nyquist frequencies:
    flat to 80 % of it, 80 dB down at it, so upsampling leaves no images and downsampling folds nothing
    back. Returns ``ceil(n · up / down)`` samples, the first at the same instant as ``values[0]``.
    """
    up, down = resample_ratio(dt, rate)
    if up == down == 1:
        return np.array(values, dtype=np.float64)
    return signal.resample_poly(values, up, down, window=_lowpass_taps(up, down))


def resample_channel(channel: ProcessedChannel, dt: float, rate: float) -> ProcessedChannel:
    """A processed channel at ``rate`` [Hz]: its acceleration resampled, then integrated again at the new rate.

    Only the acceleration is resampled: integrating it again keeps velocity and displacement its exact
    discrete integrals (a resampled displacement would carry the filter's residual images, which its second
    difference amplifies by ω²). The ends are brought to rest again (`end_correction`).
    """
    acc = resample(channel.acceleration, dt, rate)
    vel, disp = integrate_from_rest(acc, 1.0 / rate)
    acc, vel, disp, peak = _corrected(acc, vel, disp, 1.0 / rate)
    return ProcessedChannel(acc, vel, disp, channel.pad, max(peak, channel.correction_peak))
