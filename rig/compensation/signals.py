"""The accelerations iteration compares: commanded and measured, per base axis and along the fall line.

Frames as ``rig.analyze.transform``: an accelerometer on the plate measures the specific force in the plate frame
``f = Rᵀ (a − g)``, R = Ry(β) (pitch = +β takes +x down), g = (0, 0, −G). Rotated back with the run's nominal tilt:
``a = R f + g`` — the plate's acceleration in the base frame (surge, lateral, heave), what the drive commands
(its ``accelerations[:, :3]``, base-frame translations while the plate is pitched by β).

**Fall line.** The plate's acceleration along its own x axis (the fall line, +x downhill), gravity excluded:
``a_fl = a · R e_x = ax cos β − az sin β``; from the measurement that is ``fx + G sin β``. The iteration's error is
``RMS(a_fl,achieved − a_fl,target) / RMS(a_fl,target)`` in percent, and its peak error
``max |a_fl,achieved − a_fl,target| / max |a_fl,target|``, both from the record's first sample to the end of the
drive's motion (the quiet lead-in pad of the high-pass left out) and on both signals low-passed at
:data:`ERROR_BAND_HZ` (zero-phase Butterworth): the records hold nothing above it, and the accelerometers' white
noise up to 500 Hz would otherwise set a floor of a few percent on a record whose RMS is small.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, sosfiltfilt

from analysis.body import G

ERROR_BAND_HZ = 50.0
"""Both signals are compared below this frequency [Hz] (module docstring)."""


def in_band(acc: np.ndarray, rate: float, high: float = ERROR_BAND_HZ) -> np.ndarray:
    """``acc`` (n,) low-passed at ``high`` [Hz] (Butterworth order 4, forward and backward), sampled at ``rate``."""
    if high >= rate / 2:
        return np.asarray(acc, dtype=float)
    return sosfiltfilt(butter(4, high, fs=rate, output="sos"), acc)


def base_accelerations(force: np.ndarray, beta: float) -> np.ndarray:
    """Plate-frame specific force (n, 3) [m/s²] → the plate's base-frame acceleration (n, 3) [m/s²] at tilt β."""
    c, s = math.cos(beta), math.sin(beta)
    fx, fy, fz = force[:, 0], force[:, 1], force[:, 2]
    return np.column_stack([fx * c + fz * s, fy, -fx * s + fz * c - G])


def fall_line(acc: np.ndarray, beta: float) -> np.ndarray:
    """Base-frame acceleration (n, 3) [m/s²] → its component along the plate's fall line (n,) [m/s², +downhill]."""
    return acc[:, 0] * math.cos(beta) - acc[:, 2] * math.sin(beta)


def errors_pct(achieved: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """RMS and peak error [%] of ``achieved`` against ``target`` (same samples): RMS(a − t)/RMS(t) and
    max|a − t| / max|t|, in percent."""
    diff = achieved - target
    rms_t = float(np.sqrt(np.mean(target**2)))
    peak_t = float(np.max(np.abs(target)))
    if rms_t == 0.0 or peak_t == 0.0:
        raise ValueError("the target acceleration is zero: there is nothing to reproduce")
    return 100.0 * float(np.sqrt(np.mean(diff**2))) / rms_t, 100.0 * float(np.max(np.abs(diff))) / peak_t


def on_grid(rows: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Accelerometer rows (m, 4: t, ax, ay, az) interpolated linearly onto the drive's times ``t`` (n,) → (n, 3);
    ValueError when the samples do not cover the drive."""
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != 4 or len(rows) < 2:
        raise ValueError(f"expected accelerometer rows (t, ax, ay, az), got shape {rows.shape}")
    step = float(np.median(np.diff(rows[:, 0])))
    if rows[0, 0] > t[0] + step or rows[-1, 0] < t[-1] - step:
        raise ValueError(f"the accelerometer samples cover {rows[0, 0]:.3f} … {rows[-1, 0]:.3f} s, the drive "
                         f"{t[0]:.3f} … {t[-1]:.3f} s: samples are missing")
    return np.column_stack([np.interp(t, rows[:, 0], rows[:, k]) for k in (1, 2, 3)])
