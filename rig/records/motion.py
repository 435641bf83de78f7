"""The `GroundMotion` value object shared by every record reader.

A ground motion is an evenly sampled acceleration history: time step ``dt`` in seconds and the
horizontal (optionally also vertical) acceleration in units of standard gravity **g**. Readers convert
whatever the source file uses (cm/s², m/s², …) to g before building a `GroundMotion`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Acceleration of gravity used to convert m/s² to g [m/s²] (the lab's convention).
G = 9.81


class RecordError(ValueError):
    """A record could not be found, read or validated; the message says which and why."""


def array_sha256(values: np.ndarray) -> str:
    """Hex SHA-256 of an array's values as little-endian float64 bytes (C order).

    The same numbers give the same digest whatever the array's original dtype or memory layout, so the
    digest identifies the acceleration history that is actually played.
    """
    data = np.ascontiguousarray(values, dtype="<f8")
    return hashlib.sha256(data.tobytes()).hexdigest()


def _as_acceleration(name: str, label: str, values: Any) -> np.ndarray:
    """Validate one acceleration channel [g] and return it as a read-only 1-D float64 array."""
    try:
        arr = np.array(values, dtype=np.float64)  # always a copy: callers cannot alias our data
    except (TypeError, ValueError) as exc:
        raise RecordError(f"record {name!r}: {label} is not numeric ({exc})") from exc
    if arr.ndim != 1:
        raise RecordError(f"record {name!r}: {label} must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        raise RecordError(f"record {name!r}: {label} is empty")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise RecordError(
            f"record {name!r}: {label} has {bad.size} non-finite value(s) (NaN/inf), "
            f"first at sample {int(bad[0])}"
        )
    arr.setflags(write=False)
    return arr


def _as_dt(name: str, dt: Any) -> float:
    """Validate the time step [s]: a finite number > 0."""
    if isinstance(dt, bool):
        raise RecordError(f"record {name!r}: dt must be a number of seconds, got {dt!r}")
    try:
        value = float(dt)
    except (TypeError, ValueError) as exc:
        raise RecordError(f"record {name!r}: dt must be a number of seconds, got {dt!r}") from exc
    if not math.isfinite(value) or value <= 0.0:
        raise RecordError(f"record {name!r}: dt must be finite and > 0 s, got {value!r}")
    return value


@dataclass(frozen=True, eq=False)
class GroundMotion:
    """An earthquake record ready for drive preparation and analysis.

    Attributes:
        name: record name, e.g. the PEER component name ``NORTHR/MUL009`` or a file stem.
        dt: time step [s], finite and > 0.
        acc_h: horizontal acceleration [g], 1-D float64, finite, read-only. On the table it drives surge,
            along the plate's fall line (+ towards the low side once tilted).
        acc_v: vertical acceleration [g] with the same length as ``acc_h``, or ``None``; drives heave.
        acc_h2: the second horizontal component [g] of a bidirectional record (same length as ``acc_h``),
            or ``None``; drives the lateral (sway) axis.
        units: unit of ``acc_h``/``acc_v``; always ``"g"`` (readers convert at the boundary).
        provenance: where the data came from (source file or suite, record id, npts, ``sha256`` of the
            float64 ``acc_h`` values, …). JSON-serialisable values only.

    Equality is identity (arrays make value equality ambiguous); compare ``provenance["sha256"]``
    to know whether two motions carry the same horizontal history.
    """

    name: str
    dt: float
    acc_h: np.ndarray
    acc_v: np.ndarray | None = None
    acc_h2: np.ndarray | None = None
    units: str = "g"
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise RecordError(f"record name must be a non-empty string, got {self.name!r}")
        name = self.name
        if self.units != "g":
            raise RecordError(
                f"record {name!r}: units must be 'g' (convert at the reader), got {self.units!r}"
            )
        object.__setattr__(self, "dt", _as_dt(name, self.dt))
        acc_h = _as_acceleration(name, "acc_h", self.acc_h)
        object.__setattr__(self, "acc_h", acc_h)
        for label in ("acc_v", "acc_h2"):
            values = getattr(self, label)
            if values is None:
                continue
            channel = _as_acceleration(name, label, values)
            if channel.size != acc_h.size:
                raise RecordError(
                    f"record {name!r}: {label} has {channel.size} samples but acc_h has {acc_h.size}"
                )
            object.__setattr__(self, label, channel)
        object.__setattr__(self, "provenance", dict(self.provenance))

    @property
    def npts(self) -> int:
        """Number of samples."""
        return int(self.acc_h.size)

    @property
    def duration(self) -> float:
        """Time of the last sample [s]: ``(npts - 1) * dt`` (the first sample is at t = 0)."""
        return (self.npts - 1) * self.dt

    @property
    def time(self) -> np.ndarray:
        """Sample times [s], ``i * dt`` for i = 0 … npts - 1."""
        return np.arange(self.npts, dtype=np.float64) * self.dt

    @property
    def pga(self) -> float:
        """Peak horizontal ground acceleration, max |acc_h| [g]."""
        return float(np.max(np.abs(self.acc_h)))

    @property
    def pga_h2(self) -> float | None:
        """Peak of the second horizontal component, max |acc_h2| [g], or ``None`` without one."""
        return None if self.acc_h2 is None else float(np.max(np.abs(self.acc_h2)))

    @property
    def pga_v(self) -> float | None:
        """Peak vertical ground acceleration, max |acc_v| [g], or ``None`` without a vertical channel."""
        return None if self.acc_v is None else float(np.max(np.abs(self.acc_v)))

    def __repr__(self) -> str:
        extra = ("" if self.acc_h2 is None else ", +horizontal 2") + ("" if self.acc_v is None else ", +vertical")
        return (
            f"GroundMotion(name={self.name!r}, dt={self.dt:g} s, npts={self.npts}, "
            f"pga={self.pga:.4g} g{extra})"
        )
