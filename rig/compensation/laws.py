"""The two update laws of drive iteration: how a measured error becomes a correction of the drive.

Both give the correction of the drive's base-frame acceleration as a spectrum, ``ΔD(f) = G(f) · H⁺(f) · E(f)``, and
are played through the same loop (``rig.compensation.iteration``: level ramp, predicted-response check, roll-back):

- :class:`DiagonalLaw` — the per-axis method the project had first: each axis's own H1 from the identification,
  ``H⁺ = conj(H)/(|H|² + ε)`` with the absolute ε = 0.01 + (1 − γ²)/γ², a flat gain (0.8), the response never
  re-estimated, only the axes the record drives corrected;
- :class:`MimoLaw` — the response matrix (``rig.compensation.mimo``), the Tikhonov inverse scaled per line to
  σ_max², each output's error weighted by its multiple coherence, a frequency-dependent gain ``gain`` up to
  ``knee_hz`` falling log-linearly to ``gain_high`` at ``band_high`` — by default flat, 1 up to 50 Hz (the identified
  band's and the error's upper edge). The roll-off (0.3 at 45 Hz until 2026-11-27) was set on the uncoupled plant
  with ε = 0.01, where 1 up to 45 Hz left H-BCR_233 at 3.4 % against 1.5 %; on the coupled plate with ε = 0.001 the
  error it left above 30 Hz dominated (LANDERS/LCN_329 at 5°: 4 % of the target's RMS above 30 Hz after three
  full-level plays, 5.7 % in all; flat to 50 Hz: 1.7 %, H-BCR_233 1.2 %) while the coherence weighting already
  holds back what the noise dominates. The matrix is re-estimated from every play's own drive and response, all
  three axes corrected (an axis the record leaves at rest is driven to cancel the cross-coupling into it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.table.model import AXES
from rig.drive import Drive

from .identify import FrequencyResponse
from .mimo import REGULARISATION, MimoResponse
from .signals import base_accelerations


@dataclass
class DiagonalLaw:
    """Per-axis inverse, flat ``gain``, absolute ``regularisation`` (module docstring)."""

    response: FrequencyResponse
    gain: float = 0.8
    regularisation: float = 0.01
    name: str = "diagonal"

    def gains(self, freqs: np.ndarray) -> np.ndarray:
        """G(f) (n,) [-]."""
        return np.full(len(freqs), self.gain)

    def correction(self, freqs: np.ndarray, error: np.ndarray, scale: float) -> np.ndarray:
        """ΔD (n, 3) for the error spectrum (n, 3), the gain times ``scale``."""
        return self.response.correction(freqs, error, scale * self.gains(freqs), self.regularisation)

    def corrected_axes(self, drive: Drive) -> tuple[str, ...]:
        """The axes a correction may move: the record's."""
        return drive.components

    def update(self, drive: Drive, force: np.ndarray) -> None:
        """Nothing: the identification's response is kept."""


@dataclass
class MimoLaw:
    """Matrix inverse with coherence weighting and G(f), re-estimated every play (module docstring)."""

    response: MimoResponse
    gain: float = 1.0
    gain_high: float = 1.0
    knee_hz: float = 20.0
    band_high: float = 50.0
    regularisation: float = REGULARISATION
    name: str = "mimo"

    def __post_init__(self) -> None:
        if not (0 < self.gain_high <= self.gain <= 1.5 and 0 < self.knee_hz < self.band_high):
            raise ValueError(f"gains {self.gain!r} ≥ {self.gain_high!r} must be in (0, 1.5] and the knee "
                             f"{self.knee_hz!r} Hz below the band's top {self.band_high!r} Hz")

    def gains(self, freqs: np.ndarray) -> np.ndarray:
        """G(f) (n,) [-]: ``gain`` up to the knee, log-linear to ``gain_high`` at ``band_high`` and beyond."""
        f = np.clip(freqs, self.knee_hz, self.band_high)
        share = np.log(f / self.knee_hz) / math.log(self.band_high / self.knee_hz)
        return self.gain + (self.gain_high - self.gain) * share

    def correction(self, freqs: np.ndarray, error: np.ndarray, scale: float) -> np.ndarray:
        """ΔD (n, 3) for the error spectrum (n, 3), the gain times ``scale``."""
        return self.response.correction(freqs, error, scale * self.gains(freqs), self.regularisation)

    def corrected_axes(self, drive: Drive) -> tuple[str, ...]:
        """The axes a correction may move: all three."""
        return AXES

    def update(self, drive: Drive, force: np.ndarray) -> None:
        """Average the play of ``drive`` (measured plate-frame specific ``force`` (n, 3)) into the response."""
        measured = base_accelerations(force, drive.angle)
        self.response = self.response.add(drive.accelerations[:, :3], measured, drive.rate)
