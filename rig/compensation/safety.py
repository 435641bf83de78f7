"""Safety of every play: the plate's predicted response to a drive checked against the table before it is played.

**Prediction** (:func:`predicted_trajectory`). The identified response (anything with ``apply(freqs, X)``: the
per-axis ``FrequencyResponse`` or the matrix ``MimoResponse``) applied to the drive's commanded base-frame
accelerations X(f) gives the plate's predicted acceleration Y(f) = H(f) X(f) (the identity outside the identified
band). The predicted trajectory is the drive's own plus the predicted deviation ΔA = Y − X, its velocity ΔA/(iω) and
displacement −ΔA/ω² (exact in the frequency domain; ΔA vanishes below the band, so nothing grows at 0 Hz), on an
FFT of twice the drive's length (no wrap-around); the static tilt is the drive's.

**Check** (:func:`check_prediction`): that trajectory through ``TableModel.check_trajectory`` — Table IV's
displacement, velocity and acceleration per axis and the legs' stroke and speed (the hexapod's inverse kinematics),
the first breach in time. A drive whose prediction breaches a limit is not played: :class:`PredictedLimitError`
names the time, the axis or leg, the predicted value and the limit.

**Level** (:func:`at_level`): a drive's translations scaled by 10^(dB/20) (the tilt kept), how the first plays
ramp up (−12, −6, 0 dB by default).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft, rfftfreq

from analysis.table.model import Violation
from rig.drive import Drive

LEVELS_DB = (-12.0, -6.0, 0.0)
"""Default levels of the first plays [dB of the full drive]."""

LEVEL_STEP_DB = 6.0
"""Steps in which a lower starting level is looked for when the first is refused [dB]."""

LOWEST_LEVEL_DB = -40.0
"""The lowest starting level looked for [dB]: below it the accelerometers' noise would swamp the measurement."""


class Response(Protocol):
    """An identified response over its ``band`` [Hz]: the predicted output spectrum (n, 3) of an input spectrum
    (n, 3) at ``freqs``."""

    @property
    def band(self) -> tuple[float, float]: ...

    def apply(self, freqs: np.ndarray, spectrum: np.ndarray) -> np.ndarray: ...


class PredictedLimitError(RuntimeError):
    """The plate's predicted response to a drive leaves the table's limits; ``violation`` the first breach,
    ``fits_at_db`` the highest level in whole steps of ``LEVEL_STEP_DB`` below the refused one at which it fits
    (None when none down to ``LOWEST_LEVEL_DB`` does)."""

    def __init__(self, what: str, violation: Violation, fits_at_db: float | None = None) -> None:
        fits = ("" if fits_at_db is None else
                f"; at {fits_at_db:g} dB it fits: start the level ramp there")
        super().__init__(f"{what} not played: its predicted response leaves the table: {violation.message()}{fits}")
        self.violation = violation
        self.fits_at_db = fits_at_db


def predicted_trajectory(drive: Drive, response: Response) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plate's predicted poses, velocities and accelerations (n, 6) under ``drive`` (module docstring)."""
    n = len(drive.t)
    n_fft = next_fast_len(2 * n)
    freqs = rfftfreq(n_fft, 1.0 / drive.rate)
    commanded = rfft(drive.accelerations[:, :3], n_fft, axis=0)
    deviation = response.apply(freqs, commanded) - commanded
    deviation[0] = 0.0
    omega = 2.0 * math.pi * np.where(freqs > 0, freqs, 1.0)[:, None]
    poses, velocities, accelerations = drive.poses.copy(), drive.velocities.copy(), drive.accelerations.copy()
    accelerations[:, :3] += irfft(deviation, n_fft, axis=0)[:n]
    velocities[:, :3] += irfft(deviation / (1j * omega), n_fft, axis=0)[:n]
    poses[:, :3] += irfft(-deviation / omega**2, n_fft, axis=0)[:n]
    return poses, velocities, accelerations


def check_prediction(drive: Drive, response: Response) -> Violation | None:
    """The first breach of the table's limits (Table IV, the legs) by the predicted response, or None."""
    poses, velocities, accelerations = predicted_trajectory(drive, response)
    return drive.table.check_trajectory(drive.t, poses, velocities, accelerations)


def level_that_fits(drive: Drive, response: Response, refused_db: float) -> float | None:
    """The highest level ``refused_db`` − k·``LEVEL_STEP_DB`` (k ≥ 1, down to ``LOWEST_LEVEL_DB``) at which the
    prediction of ``drive`` stays within the table, or None."""
    level = refused_db - LEVEL_STEP_DB
    while level >= LOWEST_LEVEL_DB:
        if check_prediction(at_level(drive, level), response) is None:
            return level
        level -= LEVEL_STEP_DB
    return None


def predicted_peak_ratio(drive: Drive, response: Response) -> float:
    """The largest predicted |acceleration| / its Table IV limit over the three axes [-]."""
    _, _, accelerations = predicted_trajectory(drive, response)
    limits = drive.table.limits
    return max(float(np.abs(accelerations[:, k]).max()) / limits.axis(axis).acceleration
               for k, axis in enumerate(("surge", "lateral", "heave")))


def at_level(drive: Drive, level_db: float) -> Drive:
    """``drive`` with its translations scaled by 10^(level_db/20), the tilt kept (module docstring)."""
    if not (math.isfinite(level_db) and level_db <= 0.0):
        raise ValueError(f"level {level_db!r} dB: expected <= 0 dB")
    if level_db == 0.0:
        return drive
    factor = 10.0 ** (level_db / 20.0)
    poses, velocities, accelerations = drive.poses.copy(), drive.velocities.copy(), drive.accelerations.copy()
    for array in (poses, velocities, accelerations):
        array[:, :3] *= factor
    return dataclasses.replace(drive, poses=poses, velocities=velocities, accelerations=accelerations,
                               scale_factor=drive.scale_factor * factor)
