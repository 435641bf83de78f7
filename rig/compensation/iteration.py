"""Drive iteration: play, measure, correct the drive with the table's inverse response, repeat.

With the table's frequency response H per axis (``rig.compensation.identify``), iteration i played drive d_i and
measured the plate's base-frame acceleration y_i; the error against the target acceleration x (the drive as
prepared: what the record asks of the table) is e_i = x − y_i, and the next drive's acceleration is

    D_{i+1}(f) = D_i(f) + g · H⁻¹(f) · E_i(f)

per axis, with the relaxation gain g (≤ 1: a step that does not overshoot where H is uncertain) and the regularised
inverse ``conj(H) / (|H|² + ε)``, ε growing where the coherence is low (``FrequencyResponse.inverse``). The
correction is confined to the record's motion (a Tukey window) and to the band above the larger of the drive's
high-pass corner and the identified band's lower edge, up to ``band_high``; its displacement is the exact double
integral in the frequency domain (−ΔA/ω²), its velocity and acceleration the drive's plus the correction's
derivatives. Each corrected drive is checked against the table's limits (Table IV and the legs' stroke and speed,
``TableModel.check_trajectory``); when it leaves them the correction is narrowed to :data:`NARROW_BANDS_HZ`, then
its gain halved twice, else iteration stops there. Iteration stops when the fall-line RMS error
(``rig.compensation.signals``: over the record, in band) improves by less than ``min_improvement`` (relative) on
the best so far, reaches ``tolerance``, or after ``iterations`` corrections; the result is the best drive played.
With an exact H and g = 1 one step removes the error inside the band; the offline tests check the convergence on
the servo-hydraulic model (``sim_table.dynamics``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft, rfftfreq
from scipy.signal import windows

from analysis.table.model import AXES
from rig.drive import Drive

from .identify import FrequencyResponse
from .signals import base_accelerations, errors_pct, fall_line, in_band

Play = Callable[[Drive, int], np.ndarray]
"""Plays a drive (iteration index given) and returns the plate-frame specific force (n, 3) [m/s²] measured at the
drive's samples."""

NARROW_BANDS_HZ = (30.0, 20.0)
"""Upper edges of the correction [Hz] tried in turn once a correction up to ``band_high`` left the table's limits:
the highest frequencies are where the table attenuates most and the inverse amplifies most, so their content is the
first to be given up."""

BAND_HIGH = 45.0
"""Default upper edge of the correction [Hz]."""

TAPER_SECONDS = 0.5
"""Half-cosine ramps of the correction's window at both ends of the record's motion [s]."""


@dataclass(frozen=True)
class Iteration:
    """One played drive: ``index`` (0: the drive as prepared), fall-line ``rms_error_pct`` and ``peak_error_pct``,
    the relaxation ``gain`` that made it from the previous best (0 for index 0) and a ``note`` (gain reduced for the
    limits …)."""

    index: int
    rms_error_pct: float
    peak_error_pct: float
    gain: float = 0.0
    note: str = ""
    seconds: float = 0.0

    def to_json(self) -> dict[str, object]:
        return {"index": self.index, "rms_error_pct": self.rms_error_pct, "peak_error_pct": self.peak_error_pct,
                "gain": self.gain, "note": self.note, "seconds": self.seconds}


@dataclass
class Compensation:
    """The outcome: every ``iterations``' errors, the ``best`` index and its ``drive``, whether iteration
    ``converged`` (the error stopped improving or reached the tolerance, as opposed to running out of iterations
    or of room in the limits) and why it ``stopped``; the fall-line ``target`` (n,) and each iteration's
    ``achieved`` fall-line acceleration (n,) [m/s²] (both low-passed as compared), ``motion`` the samples the errors
    cover (``error_window``)."""

    iterations: list[Iteration]
    best: int
    drive: Drive
    converged: bool
    stopped: str
    target: np.ndarray
    achieved: list[np.ndarray] = field(repr=False)
    motion: slice = field(default_factory=lambda: slice(None))

    def to_json(self) -> dict[str, object]:
        return {"iterations": [it.to_json() for it in self.iterations], "best": self.best,
                "converged": self.converged, "stopped": self.stopped}


def motion_window(drive: Drive, taper: float = TAPER_SECONDS) -> tuple[slice, np.ndarray]:
    """The samples of the record's motion and a window (n,) that is 1 inside it with half-cosine ramps of ``taper``
    s at its ends, 0 outside."""
    start, end = (round(x * drive.rate) for x in drive.motion)
    end = min(end, len(drive.t))
    window = np.zeros(len(drive.t))
    length = end - start
    alpha = min(1.0, 2.0 * taper * drive.rate / max(length, 1))
    window[start:end] = windows.tukey(length, alpha=alpha)
    return slice(start, end), window


def error_window(drive: Drive) -> slice:
    """The samples the errors cover: from the record's first sample to the end of the drive's motion."""
    return slice(round(drive.record_start * drive.rate), min(round(drive.motion[1] * drive.rate), len(drive.t)))


def fall_line_errors(target: Drive, measured: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The achieved fall-line acceleration (n,) [m/s²] (in band) of the base-frame ``measured`` (n, 3) and its RMS
    and peak errors [%] against ``target``'s (``rig.compensation.signals``)."""
    beta, rate = target.angle, target.rate
    achieved = in_band(fall_line(measured, beta), rate)
    wanted = in_band(fall_line(target_acceleration(target), beta), rate)
    window = error_window(target)
    rms, peak = errors_pct(achieved[window], wanted[window])
    return achieved, rms, peak


def target_acceleration(drive: Drive) -> np.ndarray:
    """What the drive asks of the table: its base-frame translational accelerations (n, 3) [m/s²]."""
    return np.array(drive.accelerations[:, :3])


def corrected_drive(drive: Drive, error: np.ndarray, response: FrequencyResponse, gain: float, *,
                    band_high: float, regularisation: float = 0.01) -> Drive:
    """``drive`` plus ``gain`` × the inverse response applied to the acceleration ``error`` (n, 3) [m/s²]
    (module docstring)."""
    _, window = motion_window(drive)
    n = len(drive.t)
    n_fft = next_fast_len(2 * n)
    freqs = rfftfreq(n_fft, 1.0 / drive.rate)
    low = max(response.band[0], drive.corner_frequency)
    inside = (freqs >= low) & (freqs <= min(band_high, response.band[1]))
    spectrum = rfft(error * window[:, None], n_fft, axis=0)
    delta_acc = gain * response.inverse(freqs, regularisation) * spectrum * inside[:, None]
    omega = 2.0 * math.pi * np.where(freqs > 0, freqs, 1.0)
    delta = irfft(-delta_acc / (omega**2)[:, None], n_fft, axis=0)[:n] * window[:, None]
    driven = [AXES.index(axis) for axis in drive.components]
    delta[:, [c for c in range(3) if c not in driven]] = 0.0  # an axis the record does not drive stays at home
    poses, velocities, accelerations = drive.poses.copy(), drive.velocities.copy(), drive.accelerations.copy()
    dv = np.gradient(delta, axis=0) * drive.rate
    poses[:, :3] += delta
    velocities[:, :3] += dv
    accelerations[:, :3] += np.gradient(dv, axis=0) * drive.rate
    return dataclasses.replace(drive, poses=poses, velocities=velocities, accelerations=accelerations)


def compensate(drive: Drive, response: FrequencyResponse, play: Play, *, iterations: int = 5, gain: float = 0.8,
               tolerance: float = 0.0, min_improvement: float = 0.05, band_high: float = BAND_HIGH,
               regularisation: float = 0.01, clock: Callable[[], float] | None = None) -> Compensation:
    """Iterate ``drive`` on the table that ``play`` plays (module docstring); ``iterations`` corrections at most."""
    if iterations < 0 or not 0 < gain <= 1.5:
        raise ValueError(f"iterations {iterations!r} must be >= 0 and gain {gain!r} in (0, 1.5]")
    import time

    clock = clock or time.perf_counter
    beta = drive.angle
    target = target_acceleration(drive)
    target_fl = in_band(fall_line(target, beta), drive.rate)
    motion = error_window(drive)
    played: list[tuple[Drive, np.ndarray]] = []
    history: list[Iteration] = []
    achieved_fl: list[np.ndarray] = []

    def run(candidate: Drive, used_gain: float, note: str) -> Iteration:
        started = clock()
        measured = base_accelerations(play(candidate, len(history)), beta)
        achieved, rms, peak = fall_line_errors(drive, measured)
        achieved_fl.append(achieved)
        played.append((candidate, measured))
        item = Iteration(len(history), rms, peak, used_gain, note, clock() - started)
        history.append(item)
        return item

    run(drive, 0.0, "as prepared")
    stopped, converged = f"{iterations} iterations done", False
    for _ in range(iterations):
        best = min(range(len(history)), key=lambda i: history[i].rms_error_pct)
        if history[best].rms_error_pct <= tolerance:
            stopped, converged = f"the error reached the tolerance {tolerance:g} %", True
            break
        base, measured = played[best]
        error = target - measured
        bands = sorted({min(band_high, b) for b in (band_high, *NARROW_BANDS_HZ)}, reverse=True)
        narrow = bands[-1]
        notes, candidate, step = [], None, gain
        for step, high in (*((gain, b) for b in bands), (gain / 2, narrow), (gain / 4, narrow)):
            trial = corrected_drive(base, error, response, step, band_high=high, regularisation=regularisation)
            violation = trial.table.check_trajectory(trial.t, trial.poses, trial.velocities, trial.accelerations)
            if violation is None:
                candidate = trial
                break
            notes.append(f"gain {step:g} up to {high:g} Hz left the limits ({violation.message()})")
        note = "; ".join(notes)
        if candidate is None:
            stopped = f"every correction left the table's limits: {note}"
            break
        previous_best = history[best].rms_error_pct
        item = run(candidate, step, note)
        if item.rms_error_pct > previous_best * (1.0 - min_improvement):
            stopped, converged = (f"the error stopped improving ({item.rms_error_pct:.2f} % after "
                                  f"{previous_best:.2f} %)"), True
            break
    best = min(range(len(history)), key=lambda i: history[i].rms_error_pct)
    if not converged and history[best].rms_error_pct <= tolerance:
        converged = True
    return Compensation(iterations=history, best=best, drive=played[best][0], converged=converged, stopped=stopped,
                        target=target_fl, achieved=achieved_fl, motion=motion)
