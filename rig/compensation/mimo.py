"""The table's frequency-response matrix: commanded translations → measured plate acceleration, all axes at once.

**Estimate** (:func:`estimate`, :meth:`MimoResponse.add`). With x (n, p) the commanded base-frame accelerations
(surge, lateral, heave) and y (n, q) the measured ones (``rig.compensation.signals``), the Welch cross-spectral
matrices (``scipy.signal.csd``, Hann windows of ``nperseg`` samples, half overlap; scipy's convention
``S_ab = E[conj(A) B]``) are ``Sxx[i, k] = S_{x_i x_k}`` (p, p, Hermitian), ``Sxy[i, j] = S_{x_i y_j}`` (p, q) and
``Syy[j] = S_{y_j y_j}``. For a linear table y = H x + n with the noise n uncorrelated with x,
``Sxy = Sxx Hᵀ``, so the H1 estimator is

    H(f) = (Sxx⁻¹ Sxy)ᵀ        (q outputs × p inputs, per frequency line)

unbiased by output noise, and the **multiple coherence** of output j (the share of its power that the inputs
explain linearly) is ``γ²_j = Sxy[:, j]ᴴ Sxx⁻¹ Sxy[:, j] / Syy[j]``. Sxx must be invertible at every line: the
inputs must be uncorrelated (the identification drive excites the three axes with independent random signals).
The **condition number** per line is σ_max/σ_min of H (``numpy.linalg.cond``): how much an error on the
weakest direction is amplified by the inverse.

**Re-estimation.** Each play adds its spectra, weighted by its number of Welch segments, to the sums the estimate
keeps (:meth:`MimoResponse.add`): a record's play refines H where the record has power, at the level it is played,
while the identification keeps Sxx invertible where the record has none (a record's components are correlated).

**Inverse** (:meth:`MimoResponse.pseudo_inverse`): Tikhonov, scaled per line to |H|²,
``H⁺ = (Hᴴ H + ε σ_max² I)⁻¹ Hᴴ = V diag(σ / (σ² + ε σ_max²)) Uᴴ`` (SVD H = U Σ Vᴴ): the exact inverse, to a
factor 1/(1 + ε) on the strongest direction, wherever H is well conditioned, at every frequency whatever the
table's gain there; a direction weaker than √ε σ_max is given up instead of amplified. Outside the identified band
H is taken as the identity (the displacement loop follows its command at low frequency; nothing is identified
above) and the correction is zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from .identify import BAND, NPERSEG

REGULARISATION = 0.001
"""Default ε of the Tikhonov inverse, relative to σ_max² at each line [-]: a direction down to √ε σ_max ≈ σ_max/32
keeps at least half of its inverse. On the coupled plate (identified at 5° with the seven Table V bodies) heave's
gain is 6–12 times surge's and lateral's from 8 to 15 Hz (2.6 against 0.22 at 10 Hz), measured with a multiple
coherence ≥ 0.97: ε = 0.01 applied only 38–73 % of their inverse there (38–53 % at 10–15 Hz) and the fall-line
error left in 6–15 Hz shrank by about half per play (NAHANNI/S1_160: 18.5, 10.4, 6.3 % at full level); 0.001
applies 86–97 % (6.7, 3.4, 2.7 %). Where the coherence is low (above 30 Hz) the error's weighting by it and G(f)
hold the correction back."""


def _segments(n: int, nperseg: int) -> int:
    """Welch segments of half overlap in n samples."""
    return max(1, (n - nperseg) // (nperseg // 2) + 1)


def spectra(commanded: np.ndarray, measured: np.ndarray, rate: float, nperseg: int = NPERSEG
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """(f (m,) [Hz], Sxx (m, p, p), Sxy (m, p, q), Syy (m, q), segments) of commanded (n, p) and measured (n, q)
    signals sampled at ``rate`` [Hz] (module docstring)."""
    x, y = np.asarray(commanded, dtype=float), np.asarray(measured, dtype=float)
    if x.ndim != 2 or y.ndim != 2 or len(x) != len(y):
        raise ValueError(f"expected two (n, p) and (n, q) arrays over the same samples, got {x.shape} and {y.shape}")
    nperseg = min(nperseg, len(x))
    f, sxx = signal.csd(x[:, :, None], x[:, None, :], fs=rate, nperseg=nperseg, axis=0)
    _, sxy = signal.csd(x[:, :, None], y[:, None, :], fs=rate, nperseg=nperseg, axis=0)
    _, syy = signal.welch(y, fs=rate, nperseg=nperseg, axis=0)
    return f, sxx, sxy, syy, _segments(len(x), nperseg)


@dataclass(frozen=True)
class MimoResponse:
    """The response matrix (module docstring): ``f`` (m,) [Hz]; ``h`` (m, q, p) complex H1 from commanded (p) to
    measured (q) base-frame acceleration; ``coherence`` (m, q) multiple coherence per output; ``condition`` (m,);
    ``band`` [Hz] identified; the sums ``sxx``, ``sxy``, ``syy`` and their ``weight`` (segments) it came from.
    Zero H, coherence and condition outside the band or where the inputs carry no power."""

    f: np.ndarray
    h: np.ndarray
    coherence: np.ndarray
    condition: np.ndarray
    band: tuple[float, float]
    sxx: np.ndarray
    sxy: np.ndarray
    syy: np.ndarray
    weight: float
    nperseg: int

    @classmethod
    def from_spectra(cls, f: np.ndarray, sxx: np.ndarray, sxy: np.ndarray, syy: np.ndarray, weight: float,
                     band: tuple[float, float], nperseg: int) -> MimoResponse:
        """H1, multiple coherence and condition number per line from averaged spectral matrices."""
        inside = (f >= band[0]) & (f <= band[1])
        scale = np.trace(sxx, axis1=1, axis2=2).real
        inside &= scale > 0
        p, q = sxy.shape[1], sxy.shape[2]
        h = np.zeros((len(f), q, p), complex)
        coherence = np.zeros((len(f), q))
        condition = np.zeros(len(f))
        if inside.any():
            sx, sy = sxx[inside], sxy[inside]
            if np.any(np.linalg.cond(sx) > 1e12):
                line = f[inside][int(np.argmax(np.linalg.cond(sx)))]
                raise ValueError(f"the commanded axes are not independent at {line:.2f} Hz (singular input "
                                 "spectral matrix): excite every axis with uncorrelated signals")
            solved = np.linalg.solve(sx, sy)  # Sxx⁻¹ Sxy (m, p, q)
            h[inside] = np.transpose(solved, (0, 2, 1))
            explained = np.einsum("mij,mij->mj", np.conj(sy), solved).real
            with np.errstate(invalid="ignore", divide="ignore"):
                coherence[inside] = np.where(syy[inside] > 0, explained / syy[inside], 0.0)
            condition[inside] = np.linalg.cond(h[inside])
        return cls(f=f, h=h, coherence=np.clip(coherence, 0.0, 1.0), condition=condition, band=band, sxx=sxx,
                   sxy=sxy, syy=syy, weight=float(weight), nperseg=nperseg)

    def add(self, commanded: np.ndarray, measured: np.ndarray, rate: float) -> MimoResponse:
        """The estimate with one more play's commanded (n, p) and measured (n, q) accelerations averaged in
        (weighted by its Welch segments; the same ``nperseg`` and so the same lines)."""
        f, sxx, sxy, syy, segments = spectra(commanded, measured, rate, self.nperseg)
        if len(f) != len(self.f):
            raise ValueError(f"the play has {len(commanded)} samples, fewer than one Welch segment "
                             f"({self.nperseg}): its spectra do not fall on the estimate's lines")
        total = self.weight + segments

        def mix(old: np.ndarray, new: np.ndarray) -> np.ndarray:
            return (self.weight * old + segments * new) / total

        return MimoResponse.from_spectra(self.f, mix(self.sxx, sxx), mix(self.sxy, sxy), mix(self.syy, syy), total,
                                         self.band, self.nperseg)

    def at(self, freqs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """H (n, q, p) and coherence (n, q) interpolated linearly (real and imaginary parts) at ``freqs`` [Hz]
        between the identified lines (those inside the band), the nearest one's value beyond them: the zeroes
        outside the band never enter (between 0.5 Hz and the first line inside, 0.73 Hz with 4096-sample segments,
        they made H ramp from ~0 to its value — a predicted response 5 % of the table's at 0.5 Hz)."""
        known = self.inside(self.f)
        f, flat, coherence = self.f[known], self.h[known].reshape(int(known.sum()), -1), self.coherence[known]
        h = np.column_stack([np.interp(freqs, f, flat[:, k].real) + 1j * np.interp(freqs, f, flat[:, k].imag)
                             for k in range(flat.shape[1])]).reshape(len(freqs), *self.h.shape[1:])
        coh = np.column_stack([np.interp(freqs, f, coherence[:, k]) for k in range(coherence.shape[1])])
        return h, coh

    def inside(self, freqs: np.ndarray) -> np.ndarray:
        """True at the ``freqs`` [Hz] inside the identified band."""
        return (freqs >= self.band[0]) & (freqs <= self.band[1])

    def apply(self, freqs: np.ndarray, spectrum: np.ndarray) -> np.ndarray:
        """The predicted output spectrum (n, q) of the input spectrum (n, p) at ``freqs`` [Hz]: ``H X`` inside the
        band, ``X`` outside it (module docstring)."""
        h, _ = self.at(freqs)
        out = np.einsum("nqp,np->nq", h, spectrum)
        return np.where(self.inside(freqs)[:, None], out, spectrum)

    def pseudo_inverse(self, freqs: np.ndarray, regularisation: float = REGULARISATION) -> np.ndarray:
        """The Tikhonov inverse H⁺ (n, p, q) at ``freqs`` [Hz] (module docstring); zero outside the band."""
        if not regularisation >= 0:
            raise ValueError(f"regularisation {regularisation!r}: expected >= 0")
        h, _ = self.at(freqs)
        return tikhonov_inverse(h, regularisation) * self.inside(freqs)[:, None, None]

    def correction(self, freqs: np.ndarray, error: np.ndarray, gain: np.ndarray,
                   regularisation: float = REGULARISATION) -> np.ndarray:
        """The drive's acceleration correction spectrum (n, p): ``G(f) H⁺(f) (γ² E(f))`` for the error spectrum
        ``error`` (n, q) — each output's error weighted by its multiple coherence, ``gain`` (n,) the
        frequency-dependent gain."""
        _, coh = self.at(freqs)
        inverse = self.pseudo_inverse(freqs, regularisation)
        return gain[:, None] * np.einsum("npq,nq->np", inverse, coh * error)

    def peak_condition(self) -> tuple[float, float]:
        """(largest condition number, its frequency [Hz]) over the band."""
        k = int(np.argmax(self.condition))
        return float(self.condition[k]), float(self.f[k])


def tikhonov_inverse(h: np.ndarray, regularisation: float) -> np.ndarray:
    """``V diag(σ / (σ² + ε σ_max²)) Uᴴ`` of each matrix of ``h`` (..., q, p) → (..., p, q); zero for a zero
    matrix."""
    u, s, vh = np.linalg.svd(h, full_matrices=False)
    floor = regularisation * s[..., :1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.where(s > 0, s / (s**2 + floor), 0.0)
    return np.einsum("...ji,...j,...kj->...ik", np.conj(vh), factor, np.conj(u))


def estimate(commanded: np.ndarray, measured: np.ndarray, rate: float, *, band: tuple[float, float] = BAND,
             nperseg: int = NPERSEG) -> MimoResponse:
    """The response matrix (module docstring) of one play: commanded (n, p) and measured (n, q) base-frame
    accelerations [m/s²] at ``rate`` [Hz]."""
    if not 0 <= band[0] < band[1] <= rate / 2 or not math.isfinite(band[1]):
        raise ValueError(f"band {band} Hz: expected 0 <= low < high <= half the rate {rate:g} Hz")
    f, sxx, sxy, syy, segments = spectra(commanded, measured, rate, nperseg)
    return MimoResponse.from_spectra(f, sxx, sxy, syy, segments, band, min(nperseg, len(commanded)))
