"""Versioned payloads of the rig service's zenoh traffic.

Every payload starts with an 8-byte little-endian header::

    offset  size  field
    0       4     magic  b"SHKT"
    4       2     version (UNSIGNED16) = 1
    6       2     kind (UNSIGNED16, :class:`Kind`)

then the body. A reader refuses another magic, a version it does not know, an unknown kind, a kind other than
the one it expects, and a payload shorter or longer than its layout. Version 1 bodies:

- **JSON kinds** (CONTROL_REQUEST, CONTROL_REPLY, STATUS, DETECTION, RUN): one UTF-8 JSON object (no NaN or
  infinities). Each kind has required fields (:data:`REQUIRED_FIELDS`, types checked; ``int`` fields refuse
  booleans); any other field may be added freely and is passed through.

  ==================  ==================================================================================
  kind                required fields
  ==================  ==================================================================================
  CONTROL_REQUEST     ``command`` (one of the service commands, = the key's last chunk), ``args`` (object)
  CONTROL_REPLY       ``ok`` (bool), ``state`` (str: the service's state after the command), ``message`` (str)
  STATUS              ``t_ns`` (int, host time [ns]), ``state`` (str)
  DETECTION           ``t_ns`` (int), ``event_id`` (int, repeats de-duplicate), ``body_id`` (int),
                      ``direction`` (+1 towards the low side, −1 towards the high side, 0 none)
  RUN                 ``run`` (int, index in the session), ``status`` (str)
  ==================  ==================================================================================

- **ACCEL**: a batch of one accelerometer's samples (the sensor is in the key)::

      offset     size  field
      8          4     n (UNSIGNED32), number of samples
      12         8n    t_ns: int64[n], sample times [ns]
      12 + 8n    24n   acc: float64[n, 3], row-major: ax, ay, az [m/s², plate frame]

  i.e. the session file's ``accel`` columns with integer time stamps.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from enum import IntEnum
from typing import Any, NamedTuple

import numpy as np

from protocols.zenoh.keys import SERVICE_COMMANDS

MAGIC = b"SHKT"
VERSION = 1
_HEADER = struct.Struct("<4sHH")
_COUNT = struct.Struct("<I")


class Kind(IntEnum):
    """What a payload carries (header field ``kind``)."""

    CONTROL_REQUEST = 1
    CONTROL_REPLY = 2
    STATUS = 3
    ACCEL = 4
    DETECTION = 5
    RUN = 6


TELEMETRY_PAYLOADS = {"status": Kind.STATUS, "accel": Kind.ACCEL, "detection": Kind.DETECTION, "run": Kind.RUN}
"""Payload kind of each telemetry publication (by the key's telemetry kind)."""

REQUIRED_FIELDS: dict[Kind, dict[str, type]] = {
    Kind.CONTROL_REQUEST: {"command": str, "args": dict},
    Kind.CONTROL_REPLY: {"ok": bool, "state": str, "message": str},
    Kind.STATUS: {"t_ns": int, "state": str},
    Kind.DETECTION: {"t_ns": int, "event_id": int, "body_id": int, "direction": int},
    Kind.RUN: {"run": int, "status": str},
}
"""Required fields and their JSON types per JSON kind."""


class PayloadError(ValueError):
    """A payload that does not follow its layout."""


class AccelBatch(NamedTuple):
    """Samples of one accelerometer: times ``t_ns`` int64 (n,) [ns] and ``acc`` float64 (n, 3) [m/s²]."""

    t_ns: np.ndarray
    acc: np.ndarray


def _header(kind: Kind) -> bytes:
    return _HEADER.pack(MAGIC, VERSION, kind)


def read_header(payload: bytes) -> Kind:
    """The kind of a payload after checking its magic and version; :class:`PayloadError` when they are wrong."""
    data = bytes(payload)
    if len(data) < _HEADER.size:
        raise PayloadError(f"payload truncated: {len(data)} bytes, the header alone has {_HEADER.size}")
    magic, version, kind = _HEADER.unpack_from(data)
    if magic != MAGIC:
        raise PayloadError(f"not a shaketable payload: magic {magic!r}, expected {MAGIC!r}")
    if version != VERSION:
        raise PayloadError(f"payload version {version} is not supported (this reader knows version {VERSION})")
    try:
        return Kind(kind)
    except ValueError:
        raise PayloadError(f"unknown payload kind {kind} (known: "
                           f"{', '.join(f'{k.value} {k.name}' for k in Kind)})") from None


def _expect(payload: bytes, kind: Kind) -> bytes:
    found = read_header(payload)
    if found is not kind:
        raise PayloadError(f"expected a {kind.name} payload, got {found.name}")
    return bytes(payload)[_HEADER.size:]


def _check_body(kind: Kind, body: Mapping[str, Any]) -> None:
    if not isinstance(body, Mapping):
        raise PayloadError(f"{kind.name} body must be a JSON object, got {type(body).__name__}")
    for name, expected in REQUIRED_FIELDS[kind].items():
        if name not in body:
            raise PayloadError(f"{kind.name} body lacks the field {name!r}")
        value = body[name]
        if not isinstance(value, expected) or (expected is int and isinstance(value, bool)):
            raise PayloadError(f"{kind.name} field {name!r} must be {expected.__name__}, "
                               f"got {type(value).__name__} {value!r}")
    if kind is Kind.CONTROL_REQUEST and body["command"] not in SERVICE_COMMANDS:
        raise PayloadError(f"unknown command {body['command']!r}; expected one of {', '.join(SERVICE_COMMANDS)}")
    if kind is Kind.DETECTION and body["direction"] not in (-1, 0, 1):
        raise PayloadError(f"DETECTION direction must be +1, -1 or 0, got {body['direction']!r}")


def encode_json(kind: Kind, body: Mapping[str, Any]) -> bytes:
    """The payload of a JSON kind carrying ``body`` (required fields checked, others passed through)."""
    if kind not in REQUIRED_FIELDS:
        raise PayloadError(f"{getattr(kind, 'name', kind)} is not a JSON kind")
    _check_body(kind, body)
    try:
        text = json.dumps(dict(body), separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise PayloadError(f"{kind.name} body is not JSON-serialisable: {exc}") from None
    return _header(kind) + text.encode()


def decode_json(payload: bytes, kind: Kind) -> dict[str, Any]:
    """The body of a payload of JSON kind ``kind``; :class:`PayloadError` for anything else."""
    raw = _expect(payload, kind)
    try:
        body = json.loads(raw.decode(), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PayloadError(f"{kind.name} body is not UTF-8 JSON ({len(raw)} bytes): {exc}") from None
    _check_body(kind, body)
    return body


def _refuse_constant(name: str) -> float:
    raise json.JSONDecodeError(f"{name} is not JSON", name, 0)


def encode_accel(t_ns: np.ndarray, acc: np.ndarray) -> bytes:
    """The ACCEL payload of samples at integer times ``t_ns`` (n,) [ns] with accelerations ``acc`` (n, 3) [m/s²]."""
    t = np.asarray(t_ns)
    a = np.asarray(acc)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise PayloadError(f"accel t_ns must be a 1-D integer array, got {t.dtype} of shape {t.shape}")
    if a.shape != (len(t), 3) or not np.issubdtype(a.dtype, np.number):
        raise PayloadError(f"accel acc must be a numeric ({len(t)}, 3) array, got {a.dtype} of shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PayloadError("accel acc must be finite")
    return (_header(Kind.ACCEL) + _COUNT.pack(len(t)) + t.astype("<i8").tobytes()
            + a.astype("<f8").tobytes(order="C"))


def decode_accel(payload: bytes) -> AccelBatch:
    """The samples an ACCEL payload carries (fresh, writable arrays)."""
    body = _expect(payload, Kind.ACCEL)
    if len(body) < _COUNT.size:
        raise PayloadError(f"ACCEL payload truncated: body of {len(body)} bytes has no sample count")
    (n,) = _COUNT.unpack_from(body)
    expected = _COUNT.size + 32 * n
    if len(body) != expected:
        state = "truncated" if len(body) < expected else "too long"
        raise PayloadError(f"ACCEL payload {state}: {n} samples need a body of {expected} bytes, got {len(body)}")
    t = np.frombuffer(body, dtype="<i8", count=n, offset=_COUNT.size).astype(np.int64)
    acc = np.frombuffer(body, dtype="<f8", count=3 * n, offset=_COUNT.size + 8 * n).astype(np.float64)
    return AccelBatch(t, acc.reshape(n, 3))
