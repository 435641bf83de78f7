"""Measured plate-frame specific force → the inputs of the paper's models (``analysis.simulate``).

A plate accelerometer reads the specific force ``f = Rᵀ (a − g)`` [m/s², plate frame: +x downhill, z normal to the
plate, up; docs/architecture.md §2], ``R = Ry(β)``, ``g = (0, 0, −G)``. The models take the ground acceleration in
the base frame, in g: ``acc_h`` horizontal, +downhill, ``acc_v`` vertical, +up. The transform inverts the reading
at the run's nominal tilt β (its ``angle_deg``, not the logged ``pose``)::

    acc_h = ( fx cos β + fz sin β) / G
    acc_v = (−fx sin β + fz cos β − G) / G

so that the modelled block feels exactly the measured plate-frame specific force (``gx = −fx``, ``gz = fz``);
``fy`` and the plate's rotation rates are not used. Several accelerometers are averaged on a common time grid (or
one is chosen by name). Only samples from t = 0 (the drive's first sample) on are used; uniform samples (every
spacing within 1 % of the median) go to the models as they are, others are interpolated linearly onto ``t0 + k·dt``
(``dt`` the median spacing) and spacings beyond 1.5 dt reported as gaps. No filter.

Why each choice (the nominal β, no rotation rates, no low-pass, the time base): docs/measured-input.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from analysis.body import G

DESCRIPTION = (
    "acc_h = (fx cos(beta) + fz sin(beta)) / G, acc_v = (-fx sin(beta) + fz cos(beta) - G) / G with "
    "(fx, fz) the measured plate-frame specific force [m/s^2] (x along the fall line, +x downhill, z normal up), "
    "beta the run's nominal tilt (angle_deg), G = 9.81 m/s^2: the plate-frame reading rotated back to the base "
    "frame by the pitch beta and the static gravity removed (the models then feel exactly gx = -fx, gz = fz); "
    "logged pose not used, plate rotation rates neglected, fy unused; mean of the sensors on a common grid; "
    "samples from t = 0 s (the drive's first sample; uniform samples as they are from t >= -dt/2), else linear "
    "interpolation at the median spacing; no filter"
)
"""The transform in one line, as stored in the ``analysis`` groups' ``transform`` attribute."""

UNIFORM_TOLERANCE = 0.01
"""Largest relative deviation of a sample spacing from the median for samples to count as uniform [-]."""

GAP_FACTOR = 1.5
"""A spacing beyond this many median spacings counts as a gap (lost samples) [-]."""


class TransformError(ValueError):
    """The measured samples cannot be turned into model inputs (none from t = 0 on, bad shape, unknown sensor)."""


@dataclass(frozen=True)
class ModelInput:
    """The models' input derived from one run's measurement.

    ``acc_h`` [g, +downhill, horizontal] and ``acc_v`` [g, +up] sampled every ``dt`` [s] from ``t0`` [s, run
    clock]: add ``t0`` to the models' times to put them on the run's clock.
    """

    acc_h: np.ndarray
    acc_v: np.ndarray
    dt: float
    t0: float
    sensors: tuple[str, ...]
    resampled: bool
    gaps: int = 0
    longest_gap: float = 0.0
    notes: tuple[str, ...] = field(default=())

    @property
    def duration(self) -> float:
        """Time covered [s]."""
        return self.dt * max(self.acc_h.size - 1, 0)


def plate_to_model(force: np.ndarray, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Plate-frame specific force (k, 3) [m/s²] → (acc_h, acc_v) [g] at nominal tilt ``beta`` [rad] (docstring)."""
    f = np.asarray(force, dtype=float)
    if f.ndim != 2 or f.shape[1] != 3:
        raise TransformError(f"specific force: expected (k, 3) rows fx, fy, fz, got shape {f.shape}")
    cb, sb = math.cos(beta), math.sin(beta)
    ax = f[:, 0] * cb + f[:, 2] * sb
    ay = -f[:, 0] * sb + f[:, 2] * cb - G
    return ax / G, ay / G


def model_to_plate(acc_h: np.ndarray, acc_v: np.ndarray, beta: float) -> np.ndarray:
    """The inverse of `plate_to_model`: base-frame (acc_h, acc_v) [g] → plate-frame specific force (k, 3) [m/s²]
    (fy = 0), what a sensor on the plate tilted by ``beta`` [rad] reads: ``f = Ry(β)ᵀ (a − g)``."""
    ax = np.asarray(acc_h, dtype=float) * G
    gv = np.asarray(acc_v, dtype=float) * G + G
    cb, sb = math.cos(beta), math.sin(beta)
    return np.column_stack([ax * cb - gv * sb, np.zeros_like(ax), ax * sb + gv * cb])


def _from_start(samples: np.ndarray, name: str) -> np.ndarray:
    """Finite (M, 4) rows [t, fx, fy, fz] of one sensor, sorted by time, from t = 0 on (a sample just before 0
    kept when none falls exactly on it, for interpolation)."""
    arr = np.asarray(samples, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise TransformError(f"accel/{name}: expected (M, 4) rows t, ax, ay, az, got shape {arr.shape}")
    arr = arr[np.isfinite(arr).all(axis=1)]
    arr = arr[np.argsort(arr[:, 0], kind="stable")]
    first = int(np.searchsorted(arr[:, 0], 0.0, side="left"))
    if first > 0 and (first == len(arr) or arr[first, 0] > 0.0):
        first -= 1
    out = arr[first:]
    if len(out) < 2 or out[-1, 0] <= 0.0:
        raise TransformError(f"accel/{name}: fewer than 2 samples from t = 0 s on")
    return out


def _spacing(t: np.ndarray) -> tuple[float, bool, int, float]:
    """Median spacing [s], whether every spacing is within `UNIFORM_TOLERANCE` of it, gap count and longest gap."""
    d = np.diff(t)
    dt = float(np.median(d))
    if not dt > 0:
        raise TransformError("accelerometer time stamps do not advance")
    uniform = bool(np.all(np.abs(d - dt) <= UNIFORM_TOLERANCE * dt))
    big = d[d > GAP_FACTOR * dt]
    return dt, uniform, int(big.size), float(big.max()) if big.size else 0.0


def measured_inputs(accel: dict[str, np.ndarray], beta: float, sensor: str | None = None) -> ModelInput:
    """One run's ``accel`` {sensor: (M, 4) [t s, fx, fy, fz m/s²]} → `ModelInput` at nominal tilt ``beta`` [rad].

    ``sensor``: a name to use that sensor only; None for the mean of all (module docstring).
    """
    if not accel:
        raise TransformError("no accelerometer samples")
    if sensor is not None:
        if sensor not in accel:
            raise TransformError(f"sensor {sensor!r} not in the run (sensors: {sorted(accel)})")
        names = [sensor]
    else:
        names = sorted(accel)
    series = {name: _from_start(accel[name], name) for name in names}
    spacing = {name: _spacing(rows[:, 0]) for name, rows in series.items()}
    notes: list[str] = []
    first = series[names[0]]
    same_times = all(len(series[n]) == len(first) and np.array_equal(series[n][:, 0], first[:, 0]) for n in names)
    dt0, uniform0, _, _ = spacing[names[0]]
    if same_times and uniform0:
        # uniform samples on a common clock: used as they are, from the first at t >= -dt/2
        start = 1 if first[0, 0] < -0.5 * dt0 and len(first) > 2 else 0
        t = first[start:, 0]
        force = np.mean([series[n][start:, 1:] for n in names], axis=0)
        dt = float((t[-1] - t[0]) / (len(t) - 1))
        t0, resampled = float(t[0]), False
    else:
        dt = float(np.median([s[0] for s in spacing.values()]))
        t0 = max(0.0, max(float(series[n][0, 0]) for n in names))
        t_end = min(float(series[n][-1, 0]) for n in names)
        if t_end - t0 < dt:
            raise TransformError("the sensors' samples do not overlap over one sample step from t = 0 s")
        grid = t0 + dt * np.arange(math.floor((t_end - t0) / dt + 1e-9) + 1)
        force = np.mean([np.column_stack([np.interp(grid, series[n][:, 0], series[n][:, k]) for k in (1, 2, 3)])
                         for n in names], axis=0)
        resampled = True
        notes.append(f"resampled linearly to dt = {dt:.6g} s")
    gaps = sum(s[2] for s in spacing.values())
    longest = max(s[3] for s in spacing.values())
    if gaps:
        notes.append(f"{gaps} gaps in the samples (longest {longest:.4g} s), interpolated linearly")
    acc_h, acc_v = plate_to_model(force, beta)
    return ModelInput(acc_h, acc_v, dt, t0, tuple(names), resampled, gaps, longest, tuple(notes))
