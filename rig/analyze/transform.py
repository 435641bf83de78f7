"""Measured plate-frame specific force → the inputs of the paper's models (``analysis.simulate``).

**What the accelerometers measure.** A sensor fixed on the plate measures the specific force in the plate frame
(docs/architecture.md §2: x along the fall line, +x downhill, z normal to the plate, up)::

    f = Rᵀ (a − g),   g = (0, 0, −G) in the base frame,   R = Ry(β) (pitch = +β tilts +x down)

with ``a`` the plate's acceleration in the base frame. At rest on a plate tilted by β: f = (−G sin β, 0, G cos β).

**What the models take.** ``simulate(body, acc_h, dt, beta, acc_v)`` takes the *ground* (table) acceleration in
the base frame: ``acc_h`` horizontal, positive towards the downhill side, ``acc_v`` vertical, positive up, both
in g; the models tilt it themselves into the plate frame (``analysis.equations.plate_gravity``): the block feels
the effective gravity ``gx = −ax cos β + (G + ay) sin β`` along +x and ``gz = ax sin β + (G + ay) cos β`` into the
plate — the paper's Eqs. 2–10 with its reactions ``R_x``, ``R_y`` (Eqs. 3–4), whose x axis points uphill.

**The transform** inverts the measurement at the run's nominal tilt β (the run's ``angle_deg``)::

    ax = fx cos β + fz sin β              (horizontal, +downhill)      acc_h = ax / G
    ay = −fx sin β + fz cos β − G         (vertical, +up)              acc_v = ay / G

i.e. ``a = R f + g`` with R = Ry(β): rotate the plate-frame reading back to the base frame, then remove the
static gravity. Substituted into the model: ``gx = −fx`` and ``gz = fz`` *exactly*, whatever β is, so the modelled
block feels precisely the measured plate-frame specific force. That is why the nominal β is used and the logged
``pose`` is not: a tilt that differs from nominal by δ shows up in the reading as a static ``G sin δ`` along x,
which the block on the real plate does feel (it sits on that plate), and the transform passes it on to the model
unchanged. The plate's own rotation rates (the tilt is held during a run: ``pitch`` is constant in the command,
the measured pose deviates by the actuators' lag only) are neglected: they would add ``ω × (ω × r) + ω̇ × r``
for a sensor at ``r`` from the rotation centre, well below the sensor noise. The lateral reading ``fy`` is not
used: the planar models see only the fall-line plane.

**Sensors.** With several accelerometers the analysis uses their mean (each resampled to the common time grid;
for a plate in translation they read the same, and the mean halves the noise power per doubling); one can be
chosen by name instead.

**Time base and resampling.** Only samples from t = 0 (the drive's first sample, also the time base of
``commanded`` and ``detections``) on are used: the bodies stand at rest before it. When the samples are
uniform (every spacing within 1 % of the median; several sensors on the same time stamps) they go to the models
as they are, from the first sample at t ≥ −dt/2 on (``t0`` = its time: within half a step of the drive's start
when the sensor clock is not aligned to the drive's ticks; no interpolation, so a measurement equal to the
command reproduces ``simulate`` on the command to rounding). Otherwise (lost samples, jitter) they are
interpolated linearly onto ``t0 + k·dt`` from ``t0`` = max(0, first sample), with ``dt`` the median spacing;
spacings beyond 1.5 dt are counted as gaps and reported. No filter: the emulator's and a lab
MEMS sensor's noise (σ ≈ 0.02 m/s² ≈ 0.002 g) is two orders below the uplift thresholds ``G tan(α ∓ β)``
(> 0.1 g for the paper's bodies), and a low-pass would smear the pulses that decide an overturn.
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
