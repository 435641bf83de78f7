"""How well a play reproduced its target: errors per axis and along the fall line, TRAC, response-spectrum error.

All on the base-frame accelerations [m/s²] low-passed at ``signals.ERROR_BAND_HZ`` and over the record's motion
(``error_window``), target t against achieved a:

- **RMS and peak error** [%]: ``RMS(a − t)/RMS(t_ref)`` and ``max|a − t| / max|t_ref|`` with t_ref the axis's own
  target for an axis the record drives, and the fall-line target for one it does not (the cross-axis motion as a
  share of what the record asks);
- **TRAC**, the time response assurance criterion ``(tᵀa)² / ((tᵀt)(aᵀa))`` in [0, 1], 1 for a perfect shape
  (undefined, None, on an axis with no target);
- **response-spectrum error** of the fall line: the 5 %-damped pseudo-acceleration spectra (``analysis.spectrum``)
  of a and t at 40 periods spaced logarithmically over the compensated band (1/``band_high`` … 1/corner, within
  0.02–5 s), the largest and the mean |PSA_a/PSA_t − 1| [%];
- **peak / limit**: the largest |a| over the whole play against its axis's Table IV acceleration [-] (what the
  table was made to do; ≤ 1 for a play inside the limits);
- **noise floor** [%]: the fall line's RMS (about its mean) while the plate is still, before the record's motion
  (at least :data:`QUIET_SECONDS`), over the target's fall-line RMS — what the accelerometer's own noise adds to the
  RMS error of a perfect play (None without that much quiet). No correction can take the error below it, and a
  correction of an error near it mostly plays the noise back (``iteration``: the gain is scaled down there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.spectrum import DAMPING, pseudo_acceleration_spectrum
from analysis.table.model import AXES
from rig.drive import Drive

from .signals import errors_pct, fall_line, in_band

QUIET_SECONDS = 0.5
"""The least stillness before the record's motion [s] the noise floor is measured on."""


@dataclass(frozen=True)
class Measures:
    """One play's measures (module docstring): ``fall_line`` and ``axes`` (surge, lateral, heave) each a dict of
    ``rms_error_pct``, ``peak_error_pct``, ``trac`` (the fall line's also ``noise_floor_pct``);
    ``psa_error_max_pct``/``psa_error_mean_pct``; ``peak_to_limit`` and its ``peak_axis``."""

    fall_line: dict[str, float | None]
    axes: dict[str, dict[str, float | None]]
    psa_error_max_pct: float
    psa_error_mean_pct: float
    peak_to_limit: float
    peak_axis: str

    @property
    def rms_error_pct(self) -> float:
        """The fall-line RMS error [%] (what iteration minimises)."""
        return float(self.fall_line["rms_error_pct"])  # type: ignore[arg-type]  # measured: never None

    @property
    def noise_floor_pct(self) -> float | None:
        """The fall line's noise floor [%] (module docstring), None when not measured."""
        return self.fall_line.get("noise_floor_pct")

    def to_json(self) -> dict[str, Any]:
        return {"fall_line": self.fall_line, "axes": self.axes, "psa_error_max_pct": self.psa_error_max_pct,
                "psa_error_mean_pct": self.psa_error_mean_pct, "peak_to_limit": self.peak_to_limit,
                "peak_axis": self.peak_axis}


def trac(target: np.ndarray, achieved: np.ndarray) -> float | None:
    """``(tᵀa)² / ((tᵀt)(aᵀa))``; None when either signal is zero."""
    tt, aa = float(target @ target), float(achieved @ achieved)
    if tt == 0.0 or aa == 0.0:
        return None
    return float(target @ achieved) ** 2 / (tt * aa)


def noise_floor_pct(drive: Drive, achieved_fl: np.ndarray, target_fl: np.ndarray) -> float | None:
    """The noise floor [%] (module docstring) of a play whose in-band fall-line acceleration is ``achieved_fl`` (n,)
    over the whole drive, against ``target_fl`` over the error window; None when the plate is still for less than
    :data:`QUIET_SECONDS` before the motion."""
    quiet = achieved_fl[:round(drive.motion[0] * drive.rate)]
    if len(quiet) < QUIET_SECONDS * drive.rate:
        return None
    return 100.0 * float(np.std(quiet) / np.sqrt(np.mean(target_fl**2)))


def spectrum_periods(corner: float, band_high: float, count: int = 40) -> np.ndarray:
    """``count`` periods [s] spaced logarithmically over 1/band_high … 1/corner, kept within 0.02–5 s."""
    short, long = max(1.0 / band_high, 0.02), min(1.0 / max(corner, 1e-9), 5.0)
    return np.geomspace(short, long, count)


def measure(drive: Drive, target: np.ndarray, achieved: np.ndarray, window: slice, band_high: float) -> Measures:
    """The measures of base-frame ``achieved`` (n, 3) against ``target`` (n, 3) [m/s²] for ``drive`` (its tilt,
    driven axes, corner, table), over ``window``."""
    rate, beta = drive.rate, drive.angle
    t_band = np.column_stack([in_band(target[:, k], rate) for k in range(3)])
    a_band = np.column_stack([in_band(achieved[:, k], rate) for k in range(3)])
    t_fl, a_fl = fall_line(t_band, beta)[window], fall_line(a_band, beta)[window]
    rms, peak = errors_pct(a_fl, t_fl)
    fall = {"rms_error_pct": rms, "peak_error_pct": peak, "trac": trac(t_fl, a_fl),
            "noise_floor_pct": noise_floor_pct(drive, fall_line(a_band, beta), t_fl)}
    axes: dict[str, dict[str, float | None]] = {}
    for k, axis in enumerate(AXES):
        t_k, a_k = t_band[window, k], a_band[window, k]
        reference = t_k if axis in drive.components and np.any(t_k) else t_fl
        diff = a_k - t_k
        axes[axis] = {"rms_error_pct": 100.0 * float(np.sqrt(np.mean(diff**2)) / np.sqrt(np.mean(reference**2))),
                      "peak_error_pct": 100.0 * float(np.abs(diff).max() / np.abs(reference).max()),
                      "trac": trac(t_k, a_k)}
    periods = spectrum_periods(drive.corner_frequency, band_high)
    dt = 1.0 / rate
    psa_t = pseudo_acceleration_spectrum(t_fl, dt, periods, DAMPING)
    psa_a = pseudo_acceleration_spectrum(a_fl, dt, periods, DAMPING)
    ratio = np.abs(psa_a / psa_t - 1.0) * 100.0
    limits = drive.table.limits
    peaks = [float(np.abs(a_band[:, k]).max()) / limits.axis(axis).acceleration for k, axis in enumerate(AXES)]
    worst = int(np.argmax(peaks))
    return Measures(fall_line=fall, axes=axes, psa_error_max_pct=float(ratio.max()),
                    psa_error_mean_pct=float(ratio.mean()), peak_to_limit=peaks[worst], peak_axis=AXES[worst])

