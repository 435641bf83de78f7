"""Drive iteration: ramp up, play, measure, correct the drive with the table's inverse response, repeat — never
playing a drive whose predicted response leaves the table.

With the identified response H (``rig.compensation.laws``), play i of drive d_i at level s_i (a factor ≤ 1 on its
translations) measured the plate's base-frame acceleration y_i [m/s²]; against the target x (the drive as prepared)
the error brought to full level is e_i = (s_i x − y_i)/s_i, and the next drive's acceleration is

    D_{i+1}(f) = D_b(f) + G(f) · H⁺(f) · E_b(f)

from the best play b so far (the lowest fall-line RMS error), with the law's gain G(f) and inverse H⁺. Every play
is checked first, as a command against the table (``TableModel.check_command``) and as a predicted response
against Table IV and the legs (``rig.compensation.safety``): the first play is refused with
:class:`~rig.compensation.safety.PredictedLimitError`, a correction narrowed to :data:`NARROW_BANDS_HZ` and its
gain halved, else iteration stops. The plays ramp up (``levels_db``); near the accelerometer's noise floor the
gain is scaled by the Wiener factor (:func:`noise_gain`, :func:`pooled_floor`, :data:`NOISE_GAIN_MIN`); a play that
does not improve rolls back (``max_rollbacks``). The result is the best drive played at full level.

The update, the band and window, the noise floor and the roll-back: docs/compensation.md §3; the checks of every
play and the level ramp: §4; measurements: §7 and docs/notes/2026-11-27-compensation.md.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Protocol

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft, rfftfreq
from scipy.signal import windows

from analysis.table.model import AXES
from rig.drive import Drive

from .measures import Measures, measure
from .safety import (
    LEVELS_DB,
    PredictedLimitError,
    Response,
    at_level,
    check_prediction,
    level_that_fits,
    predicted_peak_ratio,
)
from .signals import base_accelerations, errors_pct, fall_line, in_band

Play = Callable[[Drive, int], np.ndarray]
"""Plays a drive (play index given) and returns the plate-frame specific force (n, 3) [m/s²] measured at the
drive's samples."""

NARROW_BANDS_HZ = (30.0, 20.0)
"""Upper edges of the correction [Hz] tried in turn once a correction up to ``band_high`` left the table's limits:
the highest frequencies are where the table attenuates most and the inverse amplifies most, so their content is the
first to be given up."""

NOISE_GAIN_MIN = 0.1
"""Below this Wiener factor (module docstring, *near the noise floor*) a full-level best play's error is the
accelerometer's noise: iteration stops."""

BAND_HIGH = 50.0
"""Default upper edge of the correction [Hz]: the identified band's and the error's (``signals.ERROR_BAND_HZ``).
It was 45 Hz until 2026-11-27: the error between 45 and 50 Hz, which no correction reached, was the largest left
(NAHANNI/S1_070 at 5°: 2.1 % of the target's RMS after three full-level plays, of 3.0 % in all)."""

TAPER_SECONDS = 0.5
"""Half-cosine ramps of the correction's window at both ends of the record's motion [s]."""


class Law(Protocol):
    """An update law (``rig.compensation.laws``)."""

    @property
    def name(self) -> str: ...

    @property
    def response(self) -> Response: ...

    def correction(self, freqs: np.ndarray, error: np.ndarray, scale: float) -> np.ndarray: ...

    def corrected_axes(self, drive: Drive) -> tuple[str, ...]: ...

    def update(self, drive: Drive, force: np.ndarray) -> None: ...


@dataclass(frozen=True)
class Iteration:
    """One play: ``index`` (0: the drive as prepared), its ``level_db``, its ``measures`` (fall-line
    ``rms_error_pct`` and ``peak_error_pct`` among them, ``peak_to_limit`` the achieved), the ``gain`` scale of the
    correction that made it (0 for index 0), a ``note`` (gain reduced for the limits, roll-back …), the ``seconds``
    the correction, its checks and the play took, and ``predicted_peak_to_limit``: the largest predicted
    |acceleration| / its Table IV limit of the play as played, by the response it was checked on."""

    index: int
    level_db: float
    measures: Measures
    gain: float = 0.0
    note: str = ""
    seconds: float = 0.0
    predicted_peak_to_limit: float = 0.0

    @property
    def rms_error_pct(self) -> float:
        return self.measures.rms_error_pct

    @property
    def peak_error_pct(self) -> float:
        return float(self.measures.fall_line["peak_error_pct"])  # type: ignore[arg-type]  # measured: never None

    def to_json(self) -> dict[str, object]:
        return {"index": self.index, "level_db": self.level_db, "rms_error_pct": self.rms_error_pct,
                "peak_error_pct": self.peak_error_pct, "gain": self.gain, "note": self.note,
                "seconds": self.seconds, "predicted_peak_to_limit": self.predicted_peak_to_limit,
                **self.measures.to_json()}


@dataclass
class Compensation:
    """The outcome: every play's ``iterations``, the ``best`` full-level play's index and its ``drive``, whether
    iteration ``converged`` (reached the tolerance or stopped improving, as opposed to running out of plays or of
    room in the limits) and why it ``stopped``; the fall-line ``target`` (n,) and each play's ``achieved``
    fall-line acceleration (n,) [m/s²] brought to full level (both low-passed as compared), ``motion`` the samples
    the errors cover (``error_window``), the ``law``'s name and its final ``response``."""

    iterations: list[Iteration]
    best: int
    drive: Drive
    converged: bool
    stopped: str
    target: np.ndarray
    achieved: list[np.ndarray] = field(repr=False)
    motion: slice = field(default_factory=lambda: slice(None))
    law: str = ""
    response: Response | None = field(default=None, repr=False)

    def to_json(self) -> dict[str, object]:
        return {"law": self.law, "iterations": [it.to_json() for it in self.iterations], "best": self.best,
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


def corrected_drive(drive: Drive, error: np.ndarray, law: Law, scale: float, *, band_high: float) -> Drive:
    """``drive`` plus the ``law``'s correction (its gain times ``scale``) of the acceleration ``error`` (n, 3)
    [m/s²] (module docstring); axes the law does not correct stay as they are."""
    _, window = motion_window(drive)
    n = len(drive.t)
    n_fft = next_fast_len(2 * n)
    freqs = rfftfreq(n_fft, 1.0 / drive.rate)
    band = law.response.band
    low = max(band[0], drive.corner_frequency)
    inside = (freqs >= low) & (freqs <= min(band_high, band[1]))
    spectrum = rfft(error * window[:, None], n_fft, axis=0)
    delta_acc = law.correction(freqs, spectrum, scale) * inside[:, None]
    omega = 2.0 * math.pi * np.where(freqs > 0, freqs, 1.0)
    delta = irfft(-delta_acc / (omega**2)[:, None], n_fft, axis=0)[:n] * window[:, None]
    corrected = [AXES.index(axis) for axis in law.corrected_axes(drive)]
    delta[:, [c for c in range(3) if c not in corrected]] = 0.0
    poses, velocities, accelerations = drive.poses.copy(), drive.velocities.copy(), drive.accelerations.copy()
    dv = np.gradient(delta, axis=0) * drive.rate
    poses[:, :3] += delta
    velocities[:, :3] += dv
    accelerations[:, :3] += np.gradient(dv, axis=0) * drive.rate
    return dataclasses.replace(drive, poses=poses, velocities=velocities, accelerations=accelerations)


def refusal(drive: Drive, law: Law) -> str | None:
    """Why ``drive`` may not be played, or None: its command leaves what the table enforces (the displacement
    envelope, the tilt, the legs' stroke and speed: ``TableModel.check_command``) or its predicted response leaves
    Table IV or the legs (``check_prediction``). The command's own velocity and acceleration are not bounded by
    Table IV: they are what the inverse asks where the table attenuates (module docstring)."""
    violation = drive.table.check_command(drive.t, drive.poses, drive.velocities, drive.accelerations)
    if violation is not None:
        return f"the command leaves the table: {violation.message()}"
    violation = check_prediction(drive, law.response)
    if violation is not None:
        return f"its predicted response leaves the table: {violation.message()}"
    return None


def noise_gain(error_pct: float, floor_pct: float | None) -> float:
    """The Wiener factor 1 − N²/M² in [0, 1] of a fall-line RMS error M and noise floor N [%] (module docstring); 1
    when the floor was not measured."""
    if floor_pct is None or error_pct <= 0.0:
        return 1.0
    return max(0.0, 1.0 - (floor_pct / error_pct) ** 2)


def pooled_floor(history: list[Iteration]) -> float | None:
    """The noise floor [%] at full level from every play so far: each play's floor times its level factor (the
    sensor's noise is the same, the target scales with the level), averaged — one play's second of stillness
    scatters by about 7 %. None when no play measured one."""
    floors = [it.measures.noise_floor_pct * 10.0 ** (it.level_db / 20.0) for it in history
              if it.measures.noise_floor_pct is not None]
    return sum(floors) / len(floors) if floors else None


def _schedule(levels_db: tuple[float, ...], iterations: int) -> list[float]:
    """The level of every play: the ramp, then full-level plays up to ``iterations`` of them."""
    if not levels_db or levels_db[-1] != 0.0 or any(b <= a for a, b in pairwise(levels_db)):
        raise ValueError(f"levels {levels_db!r} dB: expected increasing levels ending at 0 dB")
    if iterations < 1:
        raise ValueError(f"iterations {iterations!r}: expected >= 1 full-level play")
    return [*levels_db[:-1], *([0.0] * iterations)]


def _next_drive(base: Drive, error: np.ndarray, law: Law, gain_scale: float, level_db: float, band_high: float
                ) -> tuple[Drive | None, float, list[str]]:
    """The next full-level drive (module docstring): ``base`` corrected for ``error`` with the gain scaled by
    ``gain_scale`` up to ``band_high``, else up to :data:`NARROW_BANDS_HZ`, else with the gain halved twice — the
    first that may be played at full level and at ``level_db``; (None, 0, why not) when none may. Also (drive, its
    gain scale, what was given up)."""
    bands = sorted({min(band_high, b) for b in (band_high, *NARROW_BANDS_HZ)}, reverse=True)
    notes: list[str] = []
    for step, high in (*((gain_scale, b) for b in bands), (gain_scale / 2, bands[-1]), (gain_scale / 4, bands[-1])):
        trial = corrected_drive(base, error, law, step, band_high=high)
        reason = refusal(trial, law) or refusal(at_level(trial, level_db), law)
        if reason is None:
            return trial, step, notes
        notes.append(f"gain ×{step:g} up to {high:g} Hz: {reason}")
    return None, 0.0, notes


def compensate(drive: Drive, law: Law, play: Play, *, iterations: int = 4, levels_db: tuple[float, ...] = LEVELS_DB,
               tolerance: float = 0.0, band_high: float = BAND_HIGH, max_rollbacks: int = 2,
               clock: Callable[[], float] = time.perf_counter) -> Compensation:
    """Iterate ``drive`` with ``law`` on the table that ``play`` plays (module docstring): the ramp's plays, then
    ``iterations`` full-level plays at most. Raises PredictedLimitError when the drive as prepared may not be
    played even at the ramp's first level."""
    schedule = _schedule(tuple(float(x) for x in levels_db), iterations)
    target = target_acceleration(drive)
    window = error_window(drive)
    target_fl = in_band(fall_line(target, drive.angle), drive.rate)
    history: list[Iteration] = []
    played: list[tuple[Drive, float, np.ndarray]] = []  # (full-level drive, level factor, base-frame measured)
    achieved_fl: list[np.ndarray] = []
    best, rollbacks, gain_scale = -1, 0, 1.0
    stopped, converged = f"{iterations} full-level plays done", False
    for index, level_db in enumerate(schedule):
        started = clock()
        factor = 10.0 ** (level_db / 20.0)
        note, step = "as prepared", 0.0
        if index == 0:
            candidate = drive
            violation = check_prediction(at_level(drive, level_db), law.response)
            if violation is not None:
                raise PredictedLimitError(f"the drive as prepared at {level_db:g} dB", violation,
                                          level_that_fits(drive, law.response, level_db))
        else:
            base, base_factor, measured = played[best]
            error = (base_factor * target - measured) / base_factor
            best_play = history[best]
            pooled = pooled_floor(history)
            floor = None if pooled is None else pooled / base_factor  # at the best play's level
            wiener = noise_gain(best_play.rms_error_pct, floor)
            if wiener < NOISE_GAIN_MIN and best_play.level_db == 0.0:
                stopped, converged = (f"the error of play {best} ({best_play.rms_error_pct:.2f} %) is the "
                                      f"accelerometer's noise (its floor {floor:.2f} %): a correction would play the "
                                      f"noise back"), True
                break
            wiener = max(wiener, NOISE_GAIN_MIN)
            corrected, step, notes = _next_drive(base, error, law, gain_scale * wiener, level_db, band_high)
            if wiener < 1.0 - 1e-3:
                notes.insert(0, f"gain ×{wiener:.2f} near the noise floor ({floor:.2f} % of "
                                f"{best_play.rms_error_pct:.2f} %)")
            note = "; ".join(notes)
            if corrected is None:
                stopped = (f"every correction would leave the table (more headroom would give the corrections room: "
                           f"rig prepare --headroom): {note}")
                break
            candidate = corrected
        scaled = at_level(candidate, level_db)
        predicted = predicted_peak_ratio(scaled, law.response)  # what the play was checked on
        force = play(scaled, index)
        measured = base_accelerations(force, drive.angle)
        law.update(scaled, force)
        measures = measure(drive, factor * target, measured, window, band_high)
        if best >= 0 and measures.rms_error_pct >= history[best].rms_error_pct:
            rollbacks += 1
            gain_scale /= 2.0
            note = "; ".join(filter(None, (note, f"error grew: roll-back to play {best}, gain ×{gain_scale:g}")))
        history.append(Iteration(index, level_db, measures, step, note, clock() - started, predicted))
        played.append((candidate, factor, measured))
        achieved_fl.append(in_band(fall_line(measured, drive.angle), drive.rate) / factor)
        if best < 0 or measures.rms_error_pct < history[best].rms_error_pct:
            best, rollbacks = index, 0
        if level_db == 0.0 and measures.rms_error_pct <= tolerance:
            stopped, converged = f"the error reached the tolerance {tolerance:g} %", True
            break
        if rollbacks >= max_rollbacks:
            stopped, converged = f"the error stopped improving ({rollbacks} roll-backs in a row)", True
            break
    full = [k for k, it in enumerate(history) if it.level_db == 0.0]
    chosen = min(full, key=lambda k: history[k].rms_error_pct) if full else best
    if not full:
        stopped += "; no play at full level: the result is the best correction, never played at full level"
    return Compensation(iterations=history, best=chosen, drive=played[chosen][0], converged=converged,
                        stopped=stopped, target=target_fl, achieved=achieved_fl, motion=window, law=law.name,
                        response=law.response)
