"""A record → a table-ready 6-DOF drive inside the table's limits (docs/architecture.md §4).

`prepare_drive` processes each component of a `GroundMotion` (baseline, zero-phase high-pass, integration;
see `rig.drive.processing`), picks the high-pass corner, finds the largest scale factor ≤ 1 that keeps
displacement, velocity and acceleration of every axis inside the table's limits (Table IV by default), adds
the static tilt as jerk-limited ramps before and after the motion, resamples to the controller rate and
checks the whole trajectory against the hexapod's legs. A drive that cannot be played raises
`DriveRefusedError` with the first violation.

Axes: the record's first horizontal component drives **surge** (along the plate's fall line, + downhill
once tilted), the second horizontal component (``acc_h2``) **lateral**, the vertical one (``acc_v``)
**heave**; an absent component leaves its axis at home. Translations are in the base (world) frame: the
table reproduces the horizontal ground motion while its plate is tilted by pitch = +β.

**Headroom.** ``headroom`` h (0 by default; ``rig prepare --headroom 10%``, a sequence's ``headroom_pct``) is the
margin the scale factor leaves on every limit: each axis's displacement, velocity and acceleration peak stays within
(1 − h) × Table IV, and the legs' excursion from their lengths at the static tilt within (1 − h) of the stroke left
on that side and their speed within (1 − h) × the leg speed (the motion scaled down once more when the legs bind
first, their excursion being linear in the scale to first order). It is the room drive compensation needs: a
correction that asks 0.61 g of a drive scaled to 0.6 g has nowhere to go.

**Corner frequency.** The high-pass is what fits the stroke: the corner is the lowest of the candidates
``fc_min · 2^(k/4)`` (up to ``fc_max``) at which displacement no longer limits the scale factor more than
velocity or acceleration do — so as much long-period motion as the stroke allows is kept, and the scale
factor is set by velocity or acceleration as in the paper's Table VI. A record far inside the limits is
filtered at ``fc_min`` and keeps scale 1.

Timeline of a drive at the controller rate: tilt ramp 0 → β, hold ``settle`` s, the record's motion (with
the filter's pads), hold ``settle`` s, tilt ramp β → 0, then one final sample at home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.table.model import AXES, TableLimits, TableModel, Violation
from rig.records import G, GroundMotion

from . import processing, tilt

#: Which component of a `GroundMotion` drives which axis, and the pose column of that axis.
AXIS_COMPONENTS: dict[str, str] = {"surge": "acc_h", "lateral": "acc_h2", "heave": "acc_v"}
POSE_COLUMN: dict[str, int] = {"surge": 0, "lateral": 1, "heave": 2}
PITCH = 4
QUANTITIES = ("displacement", "velocity", "acceleration")

#: Lowest and highest candidate corner frequencies of the automatic high-pass [Hz]. Below 0.1 Hz (periods
#: beyond 10 s) a record carries displacement the stroke cannot hold and no acceleration that rocks a body
#: (rocking frequencies p of the study's bodies are 2.5–7 rad/s), while the filter's pads grow as 1 / fc.
FC_MIN = 0.1
FC_MAX = 5.0
#: Seconds held at the tilt before and after the motion.
SETTLE_SECONDS = 1.0
#: Largest headroom accepted (a share of every limit).
HEADROOM_MAX = 0.5


class DriveError(ValueError):
    """The drive cannot be prepared as asked (bad option, scale beyond the limits, angle beyond the tilt)."""


class DriveRefusedError(DriveError):
    """The prepared trajectory leaves the table's envelope; ``violation`` is the first breach in time."""

    def __init__(self, record: str, violation: Violation) -> None:
        super().__init__(f"drive for {record!r} refused: {violation.message()}")
        self.violation = violation


@dataclass(frozen=True)
class Governing:
    """The limit that sets the scale factor.

    ``peak`` is the processed record's peak before scaling and ``limit`` the table's bound, both SI;
    ``binding`` is False when even scale 1 stays inside every limit (then this is the closest one).
    """

    axis: str
    quantity: str
    peak: float
    limit: float
    binding: bool


@dataclass(frozen=True)
class Drive:
    """A prepared table trajectory, sampled at ``rate`` from t = 0.

    Attributes:
        record: the record's name.
        angle: static tilt β [rad] (pitch = +β during the motion).
        rate: controller rate [Hz].
        t: (N,) sample times [s].
        poses: (N, 6) surge, sway, heave [m], roll, pitch, yaw [rad] (the session file's `commanded` columns,
            `rig.session.schema`).
        velocities: (N, 6) their rates [m/s, rad/s].
        accelerations: (N, 6) their second derivatives [m/s², rad/s²].
        scale_factor: applied to every component of the record, ≤ 1.
        governing: the limit that sets ``scale_factor``.
        corner_frequency: high-pass corner [Hz].
        record_start: drive time of the record's first sample [s].
        motion: (start, end) of the processed motion in drive time [s] (the filter's pads included).
        peaks: per axis, peak |displacement| [m], |velocity| [m/s], |acceleration| [m/s²] after scaling.
        highpass_pga_ratio: per driven axis, peak acceleration after / before the high-pass (unscaled).
        components: the driven axes.
        table: the table model the drive was checked against.
        headroom: the margin left on every limit by the scale factor (a share, 0 ≤ h < 1).
    """

    record: str
    angle: float
    rate: float
    t: np.ndarray
    poses: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    scale_factor: float
    governing: Governing
    corner_frequency: float
    record_start: float
    motion: tuple[float, float]
    peaks: dict[str, dict[str, float]]
    highpass_pga_ratio: dict[str, float]
    components: tuple[str, ...]
    table: TableModel = field(repr=False)
    headroom: float = 0.0

    @property
    def duration(self) -> float:
        """Time of the last sample [s]."""
        return float(self.t[-1])

    @property
    def commanded(self) -> np.ndarray:
        """(N, 7) t, surge, sway, heave, roll, pitch, yaw — the session file's ``commanded`` layout."""
        return np.column_stack([self.t, self.poses])

    def to_json(self) -> dict[str, Any]:
        """The ``rig prepare --json`` object (accelerations in g, angles in degrees)."""
        gov = self.governing
        to_user = {"displacement": 1.0, "velocity": 1.0, "acceleration": 1.0 / G}
        return {
            "record": self.record,
            "angle_deg": math.degrees(self.angle),
            "scale_factor": self.scale_factor,
            "headroom": self.headroom,
            "governing": {
                "axis": gov.axis, "quantity": gov.quantity, "binding": gov.binding,
                "peak": gov.peak * to_user[gov.quantity], "limit": gov.limit * to_user[gov.quantity],
            },
            "peaks": {axis: {q: v * to_user[q] for q, v in peaks.items()} for axis, peaks in self.peaks.items()},
            "corner_frequency_hz": self.corner_frequency,
            "highpass_pga_ratio": self.highpass_pga_ratio,
            "duration": self.duration,
            "record_start": self.record_start,
            "motion": list(self.motion),
            "rate_hz": self.rate,
            "samples": int(self.t.size),
            "components": list(self.components),
            "units": {"displacement": "m", "velocity": "m/s", "acceleration": "g"},
        }


def _components(motion: GroundMotion) -> dict[str, np.ndarray]:
    """The record's components per axis in m/s²."""
    out = {}
    for axis, attr in AXIS_COMPONENTS.items():
        values = getattr(motion, attr)
        if values is not None:
            out[axis] = np.asarray(values, dtype=np.float64) * G
    return out


def _peaks(channels: dict[str, processing.ProcessedChannel]) -> dict[str, dict[str, float]]:
    """Peak |value| per axis and quantity (SI)."""
    return {
        axis: {
            "displacement": float(np.max(np.abs(ch.displacement))),
            "velocity": float(np.max(np.abs(ch.velocity))),
            "acceleration": float(np.max(np.abs(ch.acceleration))),
        }
        for axis, ch in channels.items()
    }


def _ratios(peaks: dict[str, dict[str, float]], limits: TableLimits) -> list[tuple[float, str, str]]:
    """(limit / peak, axis, quantity) for every axis and quantity, smallest first (inf for a zero peak)."""
    out = []
    for axis, by_quantity in peaks.items():
        bounds = limits.axis(axis)
        for quantity in QUANTITIES:
            peak = by_quantity[quantity]
            ratio = getattr(bounds, quantity) / peak if peak > 0.0 else math.inf
            out.append((ratio, axis, quantity))
    return sorted(out, key=lambda item: (item[0], AXES.index(item[1]), QUANTITIES.index(item[2])))


def _displacement_fits(peaks: dict[str, dict[str, float]], limits: TableLimits) -> bool:
    """True when displacement limits the scale no more than velocity, acceleration or 1 do."""
    ratios = _ratios(peaks, limits)
    by_disp = min(r for r, _, q in ratios if q == "displacement")
    others = min([1.0] + [r for r, _, q in ratios if q != "displacement"])
    return by_disp >= others


def corner_candidates(fc_min: float = FC_MIN, fc_max: float = FC_MAX) -> np.ndarray:
    """Candidate corners [Hz]: ``fc_min · 2^(k/4)`` up to ``fc_max`` (four per octave)."""
    count = math.floor(4.0 * math.log2(fc_max / fc_min) + 1e-9) + 1
    return fc_min * 2.0 ** (np.arange(count) / 4.0)


def _process(components: dict[str, np.ndarray], dt: float, fc: float, opts: dict[str, Any]
             ) -> dict[str, processing.ProcessedChannel]:
    """Every component through the processing chain with a common pad, then the quiet pads trimmed."""
    pad = processing.pad_samples(fc, dt, opts["order"])
    channels = {axis: processing.process_channel(acc, dt, fc, pad=pad, **opts) for axis, acc in components.items()}
    return processing.trim_pads(channels, dt, next(iter(components.values())).size)


def choose_corner(components: dict[str, np.ndarray], dt: float, limits: TableLimits, *,
                  fc_min: float = FC_MIN, fc_max: float = FC_MAX, **opts: Any
                  ) -> tuple[float, dict[str, processing.ProcessedChannel]]:
    """The automatic high-pass corner [Hz] (module docstring), evaluated at the record's own ``dt``, with the
    components processed at it."""
    nyquist = 0.5 / dt
    candidates = [fc for fc in corner_candidates(fc_min, fc_max) if fc < 0.5 * nyquist]
    if not candidates:
        raise DriveError(f"no corner frequency in [{fc_min:g}, {fc_max:g}] Hz fits below half of {nyquist:g} Hz")
    for fc in candidates:
        processed = _process(components, dt, fc, opts)
        if _displacement_fits(_peaks(processed), limits):
            break
    return float(fc), processed


def parse_headroom(text: str | float) -> float:
    """A headroom given as a share (``0.1``) or in percent (``"10%"``) → the share, in [0, `HEADROOM_MAX`]."""
    raw = str(text).strip()
    try:
        value = float(raw[:-1]) / 100.0 if raw.endswith("%") else float(raw)
    except ValueError:
        raise DriveError(f"headroom {text!r}: expected a share such as 0.1 or a percentage such as 10%") from None
    if not 0.0 <= value <= HEADROOM_MAX:
        raise DriveError(f"headroom {text!r}: expected 0 to {HEADROOM_MAX:.0%} of every limit")
    return value


def _scale(peaks: dict[str, dict[str, float]], limits: TableLimits, requested: float | None, headroom: float = 0.0
           ) -> tuple[float, Governing]:
    """The scale factor (largest ≤ 1 leaving ``headroom`` on every limit, or ``requested`` if it fits) and the
    governing limit."""
    ratio, axis, quantity = _ratios(peaks, limits)[0]
    ratio *= 1.0 - headroom
    governing = Governing(axis, quantity, peaks[axis][quantity], getattr(limits.axis(axis), quantity), ratio <= 1.0)
    largest = min(1.0, ratio)
    if requested is None:
        return largest, governing
    if not 0.0 < requested <= largest * (1.0 + 1e-12):
        margin = f" less the headroom {headroom:.0%}" if headroom else ""
        raise DriveError(
            f"scale factor {requested:g} is outside (0, {largest:.4g}]: {axis} {quantity} would reach "
            f"{requested * governing.peak:.4g} against the limit {governing.limit:.4g}{margin} (SI units)"
        )
    return requested, governing


def prepare_drive(motion: GroundMotion, *, angle: float = 0.0, table: TableModel | None = None,
                  scale: float | None = None, corner: float | None = None, rate: float | None = None,
                  settle: float = SETTLE_SECONDS, order: int = processing.FILTER_ORDER,
                  baseline_degree: int = processing.BASELINE_DEGREE, taper: float = processing.TAPER_SECONDS,
                  fc_min: float = FC_MIN, fc_max: float = FC_MAX, ramps: bool = True, headroom: float = 0.0) -> Drive:
    """Prepare ``motion`` for the table at static tilt ``angle`` [rad] (see the module docstring).

    Args:
        motion: the record (acceleration in g).
        angle: static tilt β [rad], pitch = +β; 0 for a level plate.
        table: limits, geometry and controller rate (default: Table IV and the default hexapod).
        scale: a fixed scale factor instead of the largest that fits (refused if it does not fit).
        corner: a fixed high-pass corner [Hz] instead of the automatic one.
        rate: controller rate [Hz] (default: the table's).
        settle: seconds held at the tilt before and after the motion.
        order, baseline_degree, taper: the processing chain's options (`rig.drive.processing`).
        fc_min, fc_max: range of the automatic corner [Hz].
        ramps: True: the drive starts and ends at home, tilting up to ``angle`` and back down in it; False: for
            a table already tilted (SET_TILT, as a test sequence does once per angle), it starts and ends at the
            tilt (pitch = ``angle``), only the holds of ``settle`` around the motion.

    Raises:
        DriveError: an option is out of range or a fixed ``scale`` does not fit.
        DriveRefusedError: the trajectory leaves a leg's stroke or speed, or a tilt limit.
    """
    table = table or TableModel()
    limits = table.limits
    rate = table.controller_rate if rate is None else float(rate)
    if not math.isfinite(angle) or abs(angle) > limits.tilt.angle:
        raise DriveError(
            f"angle {math.degrees(angle):g}° is beyond the table's tilt limit ±{math.degrees(limits.tilt.angle):g}°"
        )
    if not 0.0 <= headroom <= HEADROOM_MAX:
        raise DriveError(f"headroom {headroom!r}: expected 0 to {HEADROOM_MAX:g} of every limit")
    if not rate > 0.0 or settle < 0.0:
        raise DriveError(f"rate must be > 0 Hz and settle >= 0 s, got {rate!r} Hz and {settle!r} s")
    opts = {"order": order, "baseline_degree": baseline_degree, "taper": taper}
    components = _components(motion)
    dt = motion.dt
    try:
        if corner is None:
            fc, processed = choose_corner(components, dt, limits, fc_min=fc_min, fc_max=fc_max, **opts)
        else:
            fc = float(corner)
            processed = _process(components, dt, fc, opts)
        channels = {axis: processing.resample_channel(ch, dt, rate) for axis, ch in processed.items()}
    except ValueError as exc:  # a corner above Nyquist, a dt that does not resample to the rate
        raise DriveError(f"record {motion.name!r}: {exc}") from None
    unscaled_peaks = _peaks(channels)
    scale_factor, governing = _scale(unscaled_peaks, limits, scale, headroom)
    pga_ratio = {
        axis: float(np.max(np.abs(processed[axis].acceleration)) / np.max(np.abs(acc))) if np.any(acc) else 1.0
        for axis, acc in components.items()
    }
    pad_seconds = next(iter(processed.values())).pad * dt
    def assemble(factor: float) -> Drive:
        peaks = {axis: {q: 0.0 for q in QUANTITIES} for axis in AXES}
        for axis, by_quantity in unscaled_peaks.items():
            peaks[axis] = {q: factor * v for q, v in by_quantity.items()}
        return _assemble(motion.name, channels, pad_seconds, angle, rate, settle, factor, governing, fc,
                         pga_ratio, peaks, table, ramps, headroom)

    if headroom > 0.0:
        legs = _leg_usage(_assemble(motion.name, channels, pad_seconds, angle, rate, settle, scale_factor, governing,
                                    fc, pga_ratio, {}, table, ramps, headroom, check=False))
        if legs > 1.0 - headroom:
            if scale is not None:
                raise DriveError(f"scale factor {scale:g}: the legs would use {legs:.1%} of their stroke or speed, "
                                 f"more than the {1.0 - headroom:.0%} the headroom leaves")
            scale_factor *= (1.0 - headroom) / legs
    return assemble(scale_factor)

def _leg_usage(drive: Drive) -> float:
    """The largest share of the legs' room the drive's motion uses [-]: each leg's excursion from its length at the
    static tilt against the stroke left on that side, and its speed against the leg speed."""
    g = drive.table.geometry
    still = drive.poses.copy()
    still[:, :3] = 0.0
    lengths, rest = drive.table.leg_lengths(drive.poses), drive.table.leg_lengths(still)
    room = np.where(lengths >= rest, g.leg_max - rest, rest - g.leg_min)
    stroke = float(np.max(np.abs(lengths - rest) / room))
    speed = float(np.max(np.abs(drive.table.leg_velocities(drive.poses, drive.velocities)))) / g.leg_speed
    return max(stroke, speed)


def _assemble(record: str, channels: dict[str, processing.ProcessedChannel], pad_seconds: float, angle: float,
              rate: float, settle: float, scale_factor: float, governing: Governing, fc: float,
              pga_ratio: dict[str, float], peaks: dict[str, dict[str, float]], table: TableModel,
              ramps: bool, headroom: float = 0.0, check: bool = True) -> Drive:
    """Ramp up, hold, motion, hold, ramp down, home (without ``ramps``: hold, motion, hold at the tilt) — then, with
    ``check``, the check against the table model."""
    if ramps:
        ramp_time = tilt.ramp_duration(angle, table.limits.tilt, rate)
        up = tilt.ramp(0.0, angle, ramp_time, rate)
        down = tilt.ramp(angle, 0.0, ramp_time, rate)
    else:
        up = down = (np.zeros(0), np.zeros(0), np.zeros(0))
    n_ramp, n_settle = up[0].size, round(settle * rate)
    n_motion = max(ch.acceleration.size for ch in channels.values())
    n = 2 * n_ramp + 2 * n_settle + n_motion + 1
    poses, velocities, accelerations = np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6))
    first = n_ramp + n_settle
    for axis, ch in channels.items():
        col = POSE_COLUMN[axis]
        for out, values in ((poses, ch.displacement), (velocities, ch.velocity), (accelerations, ch.acceleration)):
            out[first:first + values.size, col] = scale_factor * values
    poses[n_ramp:n - 1 - n_ramp, PITCH] = angle
    if not ramps:
        poses[n - 1, PITCH] = angle
    for part, rows in ((up, slice(0, n_ramp)), (down, slice(n - 1 - n_ramp, n - 1))):
        poses[rows, PITCH] = part[0]
        velocities[rows, PITCH] = part[1]
        accelerations[rows, PITCH] = part[2]
    t = np.arange(n) / rate
    drive = Drive(
        record=record, angle=angle, rate=rate, t=t, poses=poses, velocities=velocities,
        accelerations=accelerations, scale_factor=scale_factor, governing=governing, corner_frequency=fc,
        record_start=first / rate + pad_seconds, motion=(first / rate, (first + n_motion) / rate),
        peaks=peaks, highpass_pga_ratio=pga_ratio, components=tuple(channels), table=table, headroom=headroom,
    )
    if not check:
        return drive
    violation = table.check_trajectory(t, poses, velocities, accelerations)
    if violation is not None:
        raise DriveRefusedError(record, violation)
    return drive
