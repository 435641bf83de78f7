"""How well a run's table followed its drive, as a table engineer reads it: the fall-line acceleration error, the
plate pose and the legs' strokes against their limits.

**Fall line** (as ``rig.compensation.signals``, whose functions these are): the plate's acceleration along its own
x axis (+x downhill), gravity excluded. Commanded: the commanded base-frame translations (surge, heave) twice
differentiated (central differences), ``a_fl = ax cos β − az sin β``; measured: the accelerometers' plate-frame
specific force, ``a_fl = fx + G sin β`` (the mean of the sensors), interpolated onto the commanded samples. Both are
low-passed at :data:`~rig.compensation.signals.ERROR_BAND_HZ` (zero phase) before they are compared — the records
hold nothing above it, the accelerometers' white noise would otherwise dominate — and the error
``measured − commanded`` [m/s²] is summarised by its RMS and its peak |error| over the samples both cover.

**Legs**: each leg's length [m] from the measured pose (the controller's status feedback) by the rig's inverse
kinematics (`analysis.table.model.TableModel.leg_lengths`), against the stroke limits ``leg_min``/``leg_max``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.body import G
from analysis.table.model import TableModel, TableModelError
from rig.compensation.signals import ERROR_BAND_HZ, fall_line, in_band


@dataclass(frozen=True)
class FallLineError:
    """The run's fall-line accelerations on the commanded samples: ``t`` [s], ``commanded``, ``measured`` and
    ``error`` = measured − commanded [m/s²] (all low-passed, module docstring); ``rms`` and ``peak`` of the error,
    ``rms_commanded`` of the commanded [m/s²]."""

    t: np.ndarray
    commanded: np.ndarray
    measured: np.ndarray
    error: np.ndarray
    rms: float
    peak: float
    rms_commanded: float

    @property
    def rms_percent(self) -> float:
        """The error's RMS relative to the commanded's [%] (NaN when nothing was commanded)."""
        return 100.0 * self.rms / self.rms_commanded if self.rms_commanded > 0 else math.nan


def commanded_fall_line(commanded: np.ndarray, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], commanded fall-line acceleration [m/s²]) of the commanded rows (N, 7: t, surge, sway, heave, …)."""
    if commanded.shape[0] < 3:
        return np.zeros(0), np.zeros(0)
    t = commanded[:, 0]
    acc = np.column_stack([np.gradient(np.gradient(commanded[:, k], t), t) for k in (1, 2, 3)])
    return t, fall_line(acc, beta)


def measured_fall_line(accel: dict[str, np.ndarray], beta: float, t: np.ndarray) -> np.ndarray | None:
    """The measured fall-line acceleration [m/s²] at times ``t`` (the sensors' mean, ``fx + G sin β``), NaN outside
    the samples; None without a sensor."""
    used = [a for a in accel.values() if a.ndim == 2 and a.shape[0] >= 2 and a.shape[1] >= 4]
    if not used:
        return None
    total = np.zeros_like(t)
    for rows in used:
        rows = rows[np.isfinite(rows).all(axis=1)]
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        total += np.interp(t, rows[:, 0], rows[:, 1] + G * math.sin(beta), left=np.nan, right=np.nan)
    return total / len(used)


def fall_line_error(commanded: np.ndarray, accel: dict[str, np.ndarray], beta: float) -> FallLineError | None:
    """The run's fall-line error (module docstring); None when it has no commanded or no measured samples, or
    they do not overlap."""
    t, wanted = commanded_fall_line(commanded, beta)
    if t.size < 3:
        return None
    got = measured_fall_line(accel, beta, t)
    if got is None:
        return None
    both = np.isfinite(got)
    if both.sum() < 3:
        return None
    t, wanted, got = t[both], wanted[both], got[both]
    rate = 1.0 / float(np.median(np.diff(t)))
    if t.size > 27:  # sosfiltfilt's padding needs a few filter lengths of samples
        wanted, got = in_band(wanted, rate, ERROR_BAND_HZ), in_band(got, rate, ERROR_BAND_HZ)
    error = got - wanted
    return FallLineError(t, wanted, got, error, float(np.sqrt(np.mean(error**2))), float(np.max(np.abs(error))),
                         float(np.sqrt(np.mean(wanted**2))))


@dataclass(frozen=True)
class LegStrokes:
    """The legs' lengths [m] over the run: ``t`` (K,) [s], ``lengths`` (K, 6), the stroke limits ``leg_min`` and
    ``leg_max`` [m]; ``margin`` the smallest distance of any leg to either limit [m] (negative: beyond it),
    ``closest`` which leg (1..6) and limit (``"leg_min"``/``"leg_max"``) that was."""

    t: np.ndarray
    lengths: np.ndarray
    leg_min: float
    leg_max: float
    margin: float
    closest: tuple[int, str]


def leg_strokes(pose: np.ndarray, rig_config: dict[str, Any]) -> LegStrokes | None:
    """The legs' strokes from the measured ``pose`` rows (K, 7: t, surge, sway, heave, roll, pitch, yaw) by the
    session's rig (its ``rig_config``); None without poses or without a usable rig configuration."""
    rows = pose[np.isfinite(pose).all(axis=1)] if pose.ndim == 2 and pose.shape[1] == 7 else np.zeros((0, 7))
    if not len(rows):
        return None
    try:
        model = TableModel.from_dict(rig_config, source="the session's rig_config") if rig_config else TableModel()
    except TableModelError:
        return None
    lengths = model.leg_lengths(rows[:, 1:7])
    geometry = model.geometry
    low, high = lengths - geometry.leg_min, geometry.leg_max - lengths
    k_low, k_high = np.unravel_index(np.argmin(low), low.shape), np.unravel_index(np.argmin(high), high.shape)
    if low[k_low] <= high[k_high]:
        margin, closest = float(low[k_low]), (int(k_low[1]) + 1, "leg_min")
    else:
        margin, closest = float(high[k_high]), (int(k_high[1]) + 1, "leg_max")
    return LegStrokes(rows[:, 0], lengths, geometry.leg_min, geometry.leg_max, margin, closest)
