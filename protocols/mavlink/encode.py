"""MAVLink 2 frames written directly, for the emulator's high-rate telemetry (accelerometer and tilt batches, statuses).

pymavlink packs a message in Python, field by field (a ``SHAKETABLE_ACCEL_BATCH`` is 62 struct arguments taken
from a list), which costs the emulator a large part of its tick. :class:`FrameWriter` writes the same bytes from a
payload packed with ``struct`` and numpy: the frame is MAVLink 2's —

* header: magic 0xFD, payload length, incompat flags (``SIGNED_FRAME`` when signing), compat flags 0, sequence
  number, system id, component id, message id (24 bits, little-endian);
* payload: the fields in wire order (largest type first, as mavgen orders them), trailing zero bytes cut (at
  least one byte stays), as MAVLink 2 sends it;
* checksum: CRC-16/MCRF4XX over the header after its magic byte and the payload, then the message's CRC_EXTRA;
* signature (signed links): link id, 48-bit timestamp [10 µs since 2015], and the first 6 bytes of SHA-256 over
  the key, the frame up to here, the link id and the timestamp.

The sequence number and the signing timestamp are the ones of the pymavlink ``MAVLink`` object the writer is
given, so that frames written here and messages packed by pymavlink on the same link share one sequence and one
stream of stamps; :meth:`FrameWriter.frame` advances the timestamp as ``pack()`` does (the caller advances the
sequence number, as for ``pack()``). pymavlink stays the reference: tests/transports/test_mavlink_encode.py checks
every frame written here byte for byte against ``pack()``, and the host decodes with pymavlink.
"""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Sequence
from typing import Any

import numpy as np
from fastcrc import crc16

from protocols.mavlink.codegen import dialect
from protocols.mavlink.framing import ACCEL_PER_BATCH, SEQ_MODULUS, TILT_PER_BATCH
from protocols.mavlink.signing import SIGNED_FRAME

_HEADER = struct.Struct("<BBBBBBBHB")
_CRC = struct.Struct("<H")
_STAMP = struct.Struct("<BQ")  # link id, timestamp: the first 7 bytes are the signature's prefix
_BATCH_HEAD = struct.Struct("<QII")  # t_start_ns, batch_seq, spacing_ns: the batches' wire order starts so
_ACCEL_TAIL = struct.Struct("<BB")  # sensor_id, count
_TILT_TAIL = struct.Struct("<HB")  # body_id, count
_MAGIC_V2 = 0xFD


class FrameWriter:
    """Writes MAVLink 2 frames of the dialect for the ``MAVLink`` object ``mav`` (its ids, sequence number and
    signing: key, link id and timestamp)."""

    def __init__(self, mav: Any) -> None:
        self.mav = mav
        d = dialect()
        self._accel = (d.MAVLINK_MSG_ID_SHAKETABLE_ACCEL_BATCH, d.MAVLink_shaketable_accel_batch_message.crc_extra)
        self._tilt = (d.MAVLINK_MSG_ID_SHAKETABLE_TILT_BATCH, d.MAVLink_shaketable_tilt_batch_message.crc_extra)
        status = d.MAVLink_shaketable_status_message
        self._status = (status.id, status.crc_extra)
        self._status_payload = struct.Struct(status.unpacker.format)  # the fields in wire order (t_ns first)

    def frame(self, msg_id: int, crc_extra: int, payload: bytes) -> bytes:
        """The frame of one message whose payload (every field, in wire order) is ``payload``, with the link's
        current sequence number; signed when the link signs (its timestamp then advances by one)."""
        mav = self.mav
        body = payload.rstrip(b"\0") or payload[:1]
        signing = mav.signing
        signed = bool(signing.sign_outgoing)
        head = _HEADER.pack(_MAGIC_V2, len(body), SIGNED_FRAME if signed else 0, 0, mav.seq, mav.srcSystem,
                            mav.srcComponent, msg_id & 0xFFFF, msg_id >> 16)
        crc = crc16.mcrf4xx(bytes((crc_extra,)), crc16.mcrf4xx(body, crc16.mcrf4xx(head[1:], 0xFFFF)))
        frame = head + body + _CRC.pack(crc)
        if not signed:
            return frame
        frame += _STAMP.pack(signing.link_id, signing.timestamp)[:7]
        signing.timestamp += 1
        return frame + hashlib.sha256(signing.secret_key + frame).digest()[:6]

    def accel_batch(self, samples: np.ndarray, sensor_id: int, t_start_ns: int, spacing_ns: int, seq: int) -> bytes:
        """The frame of one SHAKETABLE_ACCEL_BATCH: sensor ``sensor_id``'s samples (n ≤ :data:`ACCEL_PER_BATCH`,
        3) [m/s²] rounded to float32, as :func:`protocols.mavlink.framing.accel_batches` makes it (ValueError for a
        sample that is not finite in float32)."""
        return self._batch(self._accel, samples, 3 * ACCEL_PER_BATCH, t_start_ns, spacing_ns, seq,
                           _ACCEL_TAIL.pack(sensor_id, len(samples)))

    def tilt_batch(self, angles: np.ndarray, body_id: int, t_start_ns: int, spacing_ns: int, seq: int) -> bytes:
        """The frame of one SHAKETABLE_TILT_BATCH: body ``body_id``'s angles (n ≤ :data:`TILT_PER_BATCH`,) [rad]
        rounded to float32, as :func:`protocols.mavlink.framing.tilt_batches` makes it."""
        return self._batch(self._tilt, angles, TILT_PER_BATCH, t_start_ns, spacing_ns, seq,
                           _TILT_TAIL.pack(body_id, len(angles)))

    def status(self, t_ns: int, state: int, buffer_depth: int, last_chunk_seq: int, underruns: int, faults: int,
               refused_commands: int, pose: Sequence[float], buffer_capacity: int, samples_late: int,
               virtual_watchdog_ms: int, inputs: int, following_error: Sequence[float]) -> bytes:
        """The frame of one SHAKETABLE_STATUS, the fields as ``MAVLink_shaketable_status_message`` takes them
        (``pose``, ``following_error``: 6 values each, rounded to float32; an integer out of its field's range is a
        ``struct.error``)."""
        payload = self._status_payload.pack(t_ns, last_chunk_seq, underruns, faults, refused_commands, *pose,
                                            buffer_depth, state, buffer_capacity, samples_late, virtual_watchdog_ms,
                                            inputs, *following_error)
        return self.frame(*self._status, payload)

    def _batch(self, kind: tuple[int, int], samples: np.ndarray, size: int, t_start_ns: int, spacing_ns: int,
               seq: int, tail: bytes) -> bytes:
        flat = np.zeros(size, dtype=np.float32)
        values = np.ravel(samples)
        if len(values) > size:
            raise ValueError(f"{len(values)} values do not fit one batch of {size}")
        with np.errstate(over="ignore", invalid="ignore"):
            flat[:len(values)] = values
        if not np.isfinite(flat).all():
            raise ValueError("samples must be finite and within float32 range")
        payload = _BATCH_HEAD.pack(t_start_ns, seq % SEQ_MODULUS, spacing_ns) + flat.tobytes() + tail
        return self.frame(*kind, payload)
