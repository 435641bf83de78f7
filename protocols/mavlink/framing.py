"""Split sample arrays into the dialect's chunk messages and join received messages back into arrays.

Three streams use the same framing: setpoints (host → controller, :data:`SETPOINTS_PER_CHUNK` poses of 6 DOF per
``SHAKETABLE_SETPOINT_CHUNK``), accelerations (controller → host, :data:`ACCEL_PER_BATCH` samples of 3 axes
per ``SHAKETABLE_ACCEL_BATCH``) and body tilts (controller → host, :data:`TILT_PER_BATCH` angles of one body per
``SHAKETABLE_TILT_BATCH``). A stream is evenly spaced in time: sample ``k`` of a message is at
``t_start_ns + k * spacing_ns`` [ns, controller clock]; the last message of a split may be partial, its
``count`` saying how many samples it uses (the floats after them are zero). Consecutive messages carry
consecutive sequence numbers (``chunk_seq`` / ``batch_seq``, modulo 2^32) and continue each other in time.

Units: poses are surge, sway, heave [m], roll, pitch, yaw [rad]; accelerations ax, ay, az [m/s², plate frame];
tilts the body's rotation about the plate's y axis relative to the plate [rad], > 0 when its top has moved towards
the plate's +x (the low side).
On the wire samples are float32; arrays come back as float64 holding those float32 values exactly.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from protocols.mavlink.codegen import dialect

SETPOINTS_PER_CHUNK = 8
"""Poses in one SHAKETABLE_SETPOINT_CHUNK (``samples`` is float[48])."""

ACCEL_PER_BATCH = 19
"""Samples in one SHAKETABLE_ACCEL_BATCH (``samples`` is float[57], the most that fits a 255-byte payload)."""

TILT_PER_BATCH = 59
"""Angles in one SHAKETABLE_TILT_BATCH (``samples`` is float[59], the most that fits a 255-byte payload)."""

END_OF_STREAM = 1
"""SHAKETABLE_CHUNK_FLAGS_END_OF_STREAM: the ``flags`` bit of a stream's last setpoint chunk."""

SEQ_MODULUS = 2**32
"""Sequence numbers are uint32 and wrap."""

_U64 = 2**64


class FramingError(ValueError):
    """Messages that do not join into one stream (wrong type, bad count, time or spacing discontinuity)."""


class SequenceGapError(FramingError):
    """A sequence number other than the expected one: a message was lost, repeated or reordered."""

    def __init__(self, expected: int, got: int) -> None:
        self.expected = expected
        self.got = got
        super().__init__(f"sequence number {got} where {expected} was expected")


@dataclass(frozen=True, eq=False)
class Series:
    """Evenly spaced samples: row ``k`` of ``samples`` (N, width) is at ``t_start_ns + k * spacing_ns`` [ns]."""

    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray

    @property
    def end_ns(self) -> int:
        """Time [ns] the sample after the last would have: where the next message of the stream starts."""
        return self.t_start_ns + len(self.samples) * self.spacing_ns

    def times_ns(self) -> np.ndarray:
        """Time of every sample [ns], int64 (times beyond 2^63 ns, some 292 years, are not representable)."""
        return self.t_start_ns + self.spacing_ns * np.arange(len(self.samples), dtype=np.int64)


@dataclass(frozen=True)
class _Layout:
    msgname: str
    seq_field: str
    width: int
    per_message: int
    key_field: str | None  # a field every message of one stream shares (the sensor)
    end_flag: int  # the flags bit that ends a stream, 0 when the message has no flags field

    def message_class(self) -> Any:
        return getattr(dialect(), f"MAVLink_{self.msgname.lower()}_message")


_SETPOINT = _Layout("SHAKETABLE_SETPOINT_CHUNK", "chunk_seq", 6, SETPOINTS_PER_CHUNK, None, END_OF_STREAM)
_ACCEL = _Layout("SHAKETABLE_ACCEL_BATCH", "batch_seq", 3, ACCEL_PER_BATCH, "sensor_id", 0)
_TILT = _Layout("SHAKETABLE_TILT_BATCH", "batch_seq", 1, TILT_PER_BATCH, "body_id", 0)


def _check_int(name: str, value: int, low: int, high: int) -> None:
    if not isinstance(value, int | np.integer) or not low <= value < high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}), got {value!r}")


def _split(layout: _Layout, samples: Any, t_start_ns: int, spacing_ns: int, first_seq: int,
           fields: dict[str, int], last_fields: dict[str, int]) -> list[Any]:
    """Messages for ``samples``: ``fields`` in every one, ``last_fields`` overriding them in the last."""
    arr = np.asarray(samples, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != layout.width:
        raise ValueError(f"samples must have shape (N, {layout.width}), got {arr.shape}")
    with np.errstate(over="ignore"):
        wire = arr.astype(np.float32)
    if not np.isfinite(wire).all():
        raise ValueError("samples must be finite and within float32 range")
    _check_int("spacing_ns", spacing_ns, 1, 2**32)
    _check_int("first_seq", first_seq, 0, SEQ_MODULUS)
    _check_int("t_start_ns", t_start_ns, 0, _U64 - max(len(arr) - 1, 0) * int(spacing_ns))
    cls = layout.message_class()
    size = layout.per_message * layout.width
    starts = range(0, len(wire), layout.per_message)
    messages = []
    for k, start in enumerate(starts):
        block = wire[start:start + layout.per_message]
        flat = np.zeros(size, dtype=np.float32)
        flat[:block.size] = block.ravel()
        own = {layout.seq_field: (int(first_seq) + k) % SEQ_MODULUS,
               "t_start_ns": int(t_start_ns) + start * int(spacing_ns),
               "spacing_ns": int(spacing_ns), "count": len(block), "samples": flat.tolist()}
        messages.append(cls(**(fields | (last_fields if k == len(starts) - 1 else {}) | own)))
    return messages


def _unpack(layout: _Layout, msg: Any) -> Series:
    if msg.get_type() != layout.msgname:
        raise FramingError(f"expected {layout.msgname}, got {msg.get_type()}")
    if not 1 <= msg.count <= layout.per_message:
        raise FramingError(f"{layout.msgname}: count {msg.count} outside 1..{layout.per_message}")
    if msg.spacing_ns == 0:
        raise FramingError(f"{layout.msgname}: spacing_ns is 0")
    flat = np.asarray(msg.samples, dtype=np.float32)[:msg.count * layout.width]
    return Series(msg.t_start_ns, msg.spacing_ns, flat.reshape(msg.count, layout.width).astype(np.float64))


def _join(layout: _Layout, messages: Iterable[Any], first_seq: int | None) -> Series:
    parts: list[Series] = []
    expected = first_seq
    key = None
    ended = False
    for msg in messages:
        part = _unpack(layout, msg)
        seq = getattr(msg, layout.seq_field)
        if expected is not None and seq != expected:
            raise SequenceGapError(expected, seq)
        if layout.key_field is not None:
            value = getattr(msg, layout.key_field)
            if key is not None and value != key:
                raise FramingError(f"{layout.msgname}: {layout.key_field} {value} in a stream of {key}")
            key = value
        if parts:
            if ended:
                raise FramingError(f"{layout.seq_field} {seq} follows the end of the stream")
            if part.spacing_ns != parts[-1].spacing_ns:
                raise FramingError(f"{layout.seq_field} {seq}: spacing {part.spacing_ns} ns "
                                   f"after {parts[-1].spacing_ns} ns")
            if part.t_start_ns != parts[-1].end_ns:
                raise FramingError(f"{layout.seq_field} {seq}: starts at {part.t_start_ns} ns, "
                                   f"the stream continues at {parts[-1].end_ns} ns")
        parts.append(part)
        ended = bool(layout.end_flag and msg.flags & layout.end_flag)
        expected = (seq + 1) % SEQ_MODULUS
    if not parts:
        raise FramingError(f"no {layout.msgname} to join")
    return Series(parts[0].t_start_ns, parts[0].spacing_ns, np.concatenate([p.samples for p in parts]))


def setpoint_chunks(poses: Any, t_start_ns: int, spacing_ns: int, first_seq: int = 0, *,
                    end_of_stream: bool = False) -> list[Any]:
    """SHAKETABLE_SETPOINT_CHUNK messages for ``poses`` (N, 6) [m, m, m, rad, rad, rad], pose 0 due at
    ``t_start_ns`` [ns, controller clock], then every ``spacing_ns`` [ns]; chunk ``k`` has ``chunk_seq =
    first_seq + k`` (mod 2^32). With ``end_of_stream`` the last chunk is flagged :data:`END_OF_STREAM` (a whole
    trajectory split at once; a stream sent piecewise flags only its final piece). Poses are rounded to float32;
    non-finite ones are refused. N = 0 gives []."""
    return _split(_SETPOINT, poses, t_start_ns, spacing_ns, first_seq, {"flags": 0},
                  {"flags": END_OF_STREAM} if end_of_stream else {})


def unpack_setpoint_chunk(msg: Any) -> Series:
    """The ``count`` poses (count, 6) of one SHAKETABLE_SETPOINT_CHUNK with their timing."""
    return _unpack(_SETPOINT, msg)


def join_setpoint_chunks(messages: Iterable[Any], first_seq: int | None = None) -> Series:
    """Join chunks received in order into one :class:`Series` (N, 6).

    Raises :class:`SequenceGapError` when a ``chunk_seq`` is not the one after its predecessor's (or, for the
    first, not ``first_seq`` when given), :class:`FramingError` when spacing or time does not continue or a chunk
    follows one flagged :data:`END_OF_STREAM`.
    """
    return _join(_SETPOINT, messages, first_seq)


def accel_batches(accel: Any, sensor_id: int, t_start_ns: int, spacing_ns: int, first_seq: int = 0) -> list[Any]:
    """SHAKETABLE_ACCEL_BATCH messages for sensor ``sensor_id``'s samples ``accel`` (N, 3) [m/s², plate frame],
    sample 0 at ``t_start_ns`` [ns, controller clock], then every ``spacing_ns`` [ns]; batch ``k`` has
    ``batch_seq = first_seq + k`` (mod 2^32). Samples are rounded to float32. N = 0 gives []."""
    _check_int("sensor_id", sensor_id, 0, 256)
    return _split(_ACCEL, accel, t_start_ns, spacing_ns, first_seq, {"sensor_id": int(sensor_id)}, {})


def unpack_accel_batch(msg: Any) -> Series:
    """The ``count`` samples (count, 3) of one SHAKETABLE_ACCEL_BATCH with their timing (sensor: ``msg.sensor_id``)."""
    return _unpack(_ACCEL, msg)


def join_accel_batches(messages: Iterable[Any], first_seq: int | None = None) -> Series:
    """Join one sensor's batches received in order into one :class:`Series` (N, 3).

    Raises :class:`SequenceGapError` on a ``batch_seq`` gap, :class:`FramingError` when the sensor id, spacing or
    time does not continue.
    """
    return _join(_ACCEL, messages, first_seq)


def tilt_batches(angles: Any, body_id: int, t_start_ns: int, spacing_ns: int, first_seq: int = 0) -> list[Any]:
    """SHAKETABLE_TILT_BATCH messages for body ``body_id``'s angles ``angles`` (N,) [rad, > 0 top towards the
    plate's +x], sample 0 at ``t_start_ns`` [ns, controller clock], then every ``spacing_ns`` [ns]; batch ``k`` has
    ``batch_seq = first_seq + k`` (mod 2^32). Angles are rounded to float32. N = 0 gives []."""
    _check_int("body_id", body_id, 0, 2**16)
    arr = np.asarray(angles, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"angles must have shape (N,), got {arr.shape}")
    return _split(_TILT, arr[:, None], t_start_ns, spacing_ns, first_seq, {"body_id": int(body_id)}, {})


def unpack_tilt_batch(msg: Any) -> Series:
    """The ``count`` angles (count, 1) [rad] of one SHAKETABLE_TILT_BATCH with their timing (body: ``msg.body_id``)."""
    return _unpack(_TILT, msg)
