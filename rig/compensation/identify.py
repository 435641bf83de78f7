"""Identification: a band-limited random drive within the table's limits, and the table's frequency response.

**The drive** (:func:`identification_drive`): on each translational axis an independent Gaussian random acceleration
with a flat spectrum between ``band`` (half-cosine edges of a quarter octave), its displacement the exact double
integral in the frequency domain, faded in and out (Tukey window), scaled so that each axis's displacement, velocity
and acceleration peaks stay within ``level`` × Table IV; the plate held at the tilt β (the table is tilted by
SET_TILT before, as for a sequence's runs). It is played like any run.

**The response** (:func:`frequency_response`), per axis, from the commanded base-frame acceleration x and the
measured one y (``rig.compensation.signals``): Welch averages (``scipy.signal.welch``/``csd``, Hann windows of
``nperseg`` samples, half overlap), the H1 estimator ``H = S_xy / S_xx`` (unbiased by output noise) and the
coherence ``γ² = |S_xy|² / (S_xx S_yy)``. Axes are excited by uncorrelated inputs, so each axis's H1 is its direct
term; cross-coupling appears as lower coherence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.fft import irfft, next_fast_len, rfftfreq

from analysis.table.model import AXES, TableModel
from rig.drive import Drive, Governing

BAND = (0.5, 50.0)
"""Default band of the identification drive [Hz]."""

LEVEL = 0.3
"""Default share of Table IV the identification drive's peaks reach."""

NPERSEG = 4096
"""Default Welch segment [samples]: 0.24 Hz resolution at 1 kHz."""


@dataclass(frozen=True)
class FrequencyResponse:
    """The table's measured response per axis: ``f`` (m,) [Hz], ``h`` (m, 3) complex H1 from commanded to measured
    base-frame acceleration (surge, lateral, heave), ``coherence`` (m, 3) in [0, 1]; ``band`` [Hz] the excited
    band."""

    f: np.ndarray
    h: np.ndarray
    coherence: np.ndarray
    band: tuple[float, float]

    def at(self, freqs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """H (n, 3) and coherence (n, 3) interpolated linearly (real and imaginary parts) at ``freqs`` [Hz] between
        the identified lines (those inside the band), the nearest one's value beyond them: the zeroes outside the
        band never enter (``MimoResponse.at``)."""
        known = (self.f >= self.band[0]) & (self.f <= self.band[1])
        f, h_known, coherence = self.f[known], self.h[known], self.coherence[known]
        h = np.column_stack([np.interp(freqs, f, h_known[:, k].real) + 1j * np.interp(freqs, f, h_known[:, k].imag)
                             for k in range(3)])
        coh = np.column_stack([np.interp(freqs, f, coherence[:, k]) for k in range(3)])
        return h, coh

    def apply(self, freqs: np.ndarray, spectrum: np.ndarray) -> np.ndarray:
        """The predicted output spectrum (n, 3) of the input spectrum (n, 3) at ``freqs`` [Hz]: ``H X`` per axis
        inside the band, ``X`` outside it (``rig.compensation.safety``)."""
        h, _ = self.at(freqs)
        inside = (freqs >= self.band[0]) & (freqs <= self.band[1])
        return np.where(inside[:, None], h * spectrum, spectrum)

    def correction(self, freqs: np.ndarray, error: np.ndarray, gain: np.ndarray,
                   regularisation: float = 0.01) -> np.ndarray:
        """The drive's acceleration correction spectrum (n, 3) for the error spectrum ``error`` (n, 3): ``gain``
        (n,) × the regularised inverse per axis."""
        return gain[:, None] * self.inverse(freqs, regularisation) * error

    def inverse(self, freqs: np.ndarray, regularisation: float = 0.01) -> np.ndarray:
        """The regularised inverse (n, 3): ``conj(H) / (|H|² + ε)``, ``ε = regularisation + (1 − γ²)/γ²`` — exact
        where the coherence is 1 and H well above ε, shrinking towards 0 where the measurement is noise (γ² → 0)
        or the table does not respond; zero outside the identified band."""
        h, coh = self.at(freqs)
        coh = np.clip(coh, 1e-6, 1.0)
        eps = regularisation + (1.0 - coh) / coh
        inv = np.conj(h) / (np.abs(h) ** 2 + eps)
        inside = (freqs >= self.band[0]) & (freqs <= self.band[1])
        return np.where(inside[:, None], inv, 0.0)


def _band_shape(freqs: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    """1 inside ``band``, half-cosine edges over a quarter octave outside it, 0 beyond."""
    lo, hi = band
    shape = np.zeros_like(freqs)
    edge = 2.0**0.25
    shape[(freqs >= lo) & (freqs <= hi)] = 1.0
    for inner, outer in ((lo, lo / edge), (hi, hi * edge)):
        a, b = sorted((inner, outer))
        part = (freqs > a) & (freqs < b) & ~((freqs >= lo) & (freqs <= hi))
        x = np.abs(np.log(freqs[part] / inner) / np.log(outer / inner))
        shape[part] = 0.5 * (1.0 + np.cos(math.pi * x))
    return shape


def identification_drive(table: TableModel, angle: float, *, duration: float = 60.0,
                         band: tuple[float, float] = BAND, level: float = LEVEL, axes: tuple[str, ...] = AXES,
                         settle: float = 1.0, seed: int = 0) -> Drive:
    """The band-limited random drive (module docstring) of ``duration`` s at tilt ``angle`` [rad] on ``axes``."""
    if not (0 < band[0] < band[1] < table.controller_rate / 2):
        raise ValueError(f"band {band} Hz: expected 0 < low < high < half the controller rate")
    if not 0 < level <= 1:
        raise ValueError(f"level {level!r}: expected a share of Table IV in (0, 1]")
    rate = table.controller_rate
    n_motion = round(duration * rate)
    n_settle = round(settle * rate)
    n_fft = next_fast_len(n_motion)
    freqs = rfftfreq(n_fft, 1.0 / rate)
    shape = _band_shape(freqs, band)
    omega = 2.0 * math.pi * np.where(freqs > 0, freqs, 1.0)
    rng = np.random.default_rng(seed)
    fade = signal.windows.tukey(n_motion, alpha=min(1.0, 2 * 4.0 / duration))
    n = 2 * n_settle + n_motion + 1
    poses: NDArray[np.float64] = np.zeros((n, 6))  # (n, 6) [m, rad]
    poses[:, 4] = angle
    for axis in axes:
        column = AXES.index(axis)
        spectrum = shape * (rng.normal(size=freqs.size) + 1j * rng.normal(size=freqs.size))
        displacement = irfft(-spectrum / omega**2, n_fft)[:n_motion] * fade
        displacement -= np.linspace(displacement[0], displacement[-1], n_motion)
        limits = table.limits.axis(axis)
        velocity = np.gradient(displacement) * rate
        acceleration = np.gradient(velocity) * rate
        ratio = max(np.abs(displacement).max() / limits.displacement, np.abs(velocity).max() / limits.velocity,
                    np.abs(acceleration).max() / limits.acceleration)
        poses[n_settle:n_settle + n_motion, column] = displacement * level / ratio
    t = np.arange(n) / rate
    velocities = np.gradient(poses, t, axis=0)
    accelerations = np.gradient(velocities, t, axis=0)
    surge = table.limits.surge
    drive = Drive(record=f"identification {band[0]:g}-{band[1]:g} Hz", angle=angle, rate=rate, t=t, poses=poses,
                  velocities=velocities, accelerations=accelerations, scale_factor=level,
                  governing=Governing("surge", "acceleration", level * surge.acceleration, surge.acceleration, False),
                  corner_frequency=band[0], record_start=n_settle / rate,
                  motion=(n_settle / rate, (n_settle + n_motion) / rate),
                  peaks={a: {q: float(level * getattr(table.limits.axis(a), q)) if a in axes else 0.0
                             for q in ("displacement", "velocity", "acceleration")} for a in AXES},
                  highpass_pga_ratio={}, components=tuple(axes), table=table)
    violation = table.check_trajectory(t, poses, velocities, accelerations)
    if violation is not None:
        raise ValueError(f"the identification drive leaves the table: {violation.message()}")
    return drive


def frequency_response(commanded: np.ndarray, measured: np.ndarray, rate: float, *,
                       band: tuple[float, float] = BAND, nperseg: int = NPERSEG) -> FrequencyResponse:
    """H1 and coherence per axis (module docstring) from commanded and measured base-frame accelerations (n, 3)
    [m/s²] sampled at ``rate`` [Hz] over the same instants."""
    if commanded.shape != measured.shape or commanded.ndim != 2 or commanded.shape[1] != 3:
        raise ValueError(f"expected two (n, 3) arrays, got {commanded.shape} and {measured.shape}")
    nperseg = min(nperseg, len(commanded))
    f, pxx = signal.welch(commanded, fs=rate, nperseg=nperseg, axis=0)
    _, pyy = signal.welch(measured, fs=rate, nperseg=nperseg, axis=0)
    _, pxy = signal.csd(commanded, measured, fs=rate, nperseg=nperseg, axis=0)
    inside = ((f >= band[0]) & (f <= band[1]))[:, None] & (pxx > 0) & (pyy > 0)  # unexcited: no estimate
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(inside, pxy / pxx, 0.0)
        coherence = np.where(inside, np.abs(pxy) ** 2 / (pxx * pyy), 0.0)
    return FrequencyResponse(f=f, h=h, coherence=np.clip(coherence, 0.0, 1.0), band=band)
