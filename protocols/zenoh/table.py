"""The table link over zenoh: its URL and the binary payloads of ``shaketable/<table>/controller/...``.

The link between the lab host (``drivers.zenoh``) and the table controller (``sim_table.zenoh_endpoint``) carries
the behaviour of ``docs/table-controller.md``; keys are :func:`protocols.zenoh.keys.table_key`, signatures
:mod:`protocols.zenoh.auth`. URL: ``zenoh://HOST:PORT/TABLE`` — the controller's zenoh session listens on
``tls/HOST:PORT`` when the processes have a TLS identity, else on ``tcp/HOST:PORT`` (loopback unless explicitly
insecure: :func:`protocols.zenoh.session_config`); ``TABLE`` names the table in the key space (default
:data:`DEFAULT_TABLE`).

Every payload starts with an 8-byte little-endian header ``magic b"SHTC", version (UNSIGNED16) = 1, kind
(UNSIGNED16, :class:`TableKind`)`` (the rig service's payloads, :mod:`protocols.zenoh.payloads`, use another
magic), then a fixed little-endian body. On the link every payload travels with a 48-byte signature trailer
(:mod:`protocols.zenoh.auth`): COMMAND and SETPOINTS are decoded with it (:func:`decode_command`,
:func:`decode_setpoints` split it off; unsigned ones are refused by the controller), the other kinds are decoded
from the message :func:`protocols.zenoh.auth.split_signed` leaves once the signature verified. Units: times
integer ns (controller time unless said), poses ``(surge, sway, heave [m], roll, pitch, yaw [rad])``,
accelerations [m/s², plate frame, specific force], a body's tilt [rad] its rotation about the plate's y axis
relative to the plate, > 0 when its top has moved towards the plate's +x (the low side).

The body of each kind, field by field: docs/transports.md §zenoh: the payloads of version 1. A reader refuses
another magic or version, an unknown kind or code, a kind other than the one it expects, and a length other than
the layout's.
"""

from __future__ import annotations

import ipaddress
import math
import struct
from enum import IntEnum
from typing import NamedTuple
from urllib.parse import urlsplit

import numpy as np

from protocols.zenoh.auth import TRAILER_BYTES, Received
from protocols.zenoh.config import PLAIN, LinkSecurity
from protocols.zenoh.keys import check_name
from protocols.zenoh.payloads import PayloadError

MAGIC = b"SHTC"
VERSION = 1
DEFAULT_TABLE = "table"
"""Table name of a URL without one."""

COMMANDS = ("arm", "disarm", "home", "set_tilt", "start_stream", "stop", "emergency_stop", "claim", "release",
            "set_limit")
"""Command codes (index)."""

RESULTS = ("accepted", "in_progress", "denied", "rejected", "failed", "cancelled")
"""Answer codes (index): accepted; in progress (HOME, SET_TILT: a final ANSWER follows); denied (missing or bad
signature); rejected (not in this state); failed (invalid parameters); cancelled (a motion stopped before its end)."""

STATES = ("idle", "armed", "homing", "tilting", "streaming", "stopping", "faulted", "emergency_stopped")
"""State codes (index)."""

FAULTS = ("DRIVE", "STROKE", "STREAM_SILENT", "HEARTBEAT_LOST", "UNSIGNED_COMMAND", "SETPOINT_LIMIT", "CHUNK_GAP",
          "UNDERRUN", "SETPOINT_REFUSED")
"""Fault bit ``1 << i`` is ``FAULTS[i]``."""

END_OF_STREAM = 1
"""SETPOINTS flag: the last chunk of the stream."""

SETPOINTS_PER_CHUNK = 10
"""Samples the host puts in a chunk (10 ms at 1 kHz)."""

MAX_REASON = 1000
"""Most bytes of a REFUSAL's reason."""

MAX_SAMPLES = 1000
"""Most samples in one SETPOINTS payload."""

ACCEL_PER_BATCH = 50
"""Samples the controller puts in an accelerometer batch (50 ms at 1 kHz)."""

TILT_PER_BATCH = 10
"""Samples the controller puts in a body's tilt batch (50 ms at 200 Hz)."""

_HEADER = struct.Struct("<4sHH")
_COMMAND = struct.Struct("<QBdd")
_ANSWER = struct.Struct("<QBq")
_CLOCK_REQUEST = struct.Struct("<q")
_CLOCK_REPLY = struct.Struct("<qq")
_SETPOINTS = struct.Struct("<IBqqH")
_STATUS = struct.Struct("<qBIIIII6dIIII6d")
_STATUS_NO_LEGS = struct.Struct("<qBIIIII6dIIII")
"""A status without its last field (the legs' ``following_error``), as a controller that does not report it may
send it."""
_STATUS_REAL_TIME = struct.Struct("<qBIIIII6dII")
"""A status without its last two fields (``virtual_watchdog_ms``, ``inputs``), as a controller that keeps real time
and has no interlock inputs may send it."""
_STATUS_NO_INPUTS = struct.Struct("<qBIIIII6dIII")
"""A status without its last field (``inputs``), as a controller without interlock inputs may send it."""
_ACCEL = struct.Struct("<HIqqI")
_OVERTURN = struct.Struct("<QIbdq")
_HEARTBEAT = struct.Struct("<q")
_TILT = struct.Struct("<IIqqI")
_BODY = struct.Struct("<5d")
_COUNT = struct.Struct("<H")
_REFUSAL = struct.Struct("<qIH")
_OWNER = struct.Struct("<QqIIH")
_LIMIT_TRIP = struct.Struct("<qHIdd")


class TableKind(IntEnum):
    """What a table link payload carries (header field ``kind``)."""

    COMMAND = 1
    ANSWER = 2
    CLOCK_REQUEST = 3
    CLOCK_REPLY = 4
    SETPOINTS = 5
    STATUS = 6
    ACCEL = 7
    OVERTURN = 8
    HEARTBEAT = 9
    TILT = 10
    BODIES = 11
    REFUSAL = 12
    OWNER = 13
    LIMIT_TRIP = 14


class TableUrl(NamedTuple):
    """A parsed ``zenoh://HOST:PORT/TABLE``: ``host`` an IP address, ``port`` (0: any free one) and ``table`` name."""

    host: str
    port: int
    table: str

    @property
    def endpoint(self) -> str:
        """The controller's plain zenoh endpoint ``tcp/HOST:PORT`` (loopback)."""
        return self.endpoint_for(PLAIN)

    def endpoint_for(self, security: LinkSecurity) -> str:
        """The controller's zenoh endpoint with ``security``: ``tls/HOST:PORT`` with a TLS identity, else
        ``tcp/HOST:PORT`` (:class:`~protocols.zenoh.config.EndpointError` off loopback unless insecure)."""
        return security.endpoint(self.host, self.port)

    @property
    def url(self) -> str:
        """The URL again (``zenoh://127.0.0.1:7447/table``)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"zenoh://{host}:{self.port}/{self.table}"


class CommandRequest(NamedTuple):
    """A command: the host's ``cmd_id``, ``command`` (one of :data:`COMMANDS`), two parameters."""

    cmd_id: int
    command: str
    params: tuple[float, float]


class Answer(NamedTuple):
    """The controller's answer to command ``cmd_id``: ``result`` (one of :data:`RESULTS`) at ``t_ns``."""

    cmd_id: int
    result: str
    t_ns: int


class ClockReply(NamedTuple):
    """The answer to a clock request sent at host ``t_send_ns``: controller time ``t_controller_ns``."""

    t_send_ns: int
    t_controller_ns: int


class SetpointChunk(NamedTuple):
    """Setpoint chunk ``seq``: ``samples`` (n, 6), row k due at ``t_start_ns + k * spacing_ns``."""

    seq: int
    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray
    end_of_stream: bool


class StatusReport(NamedTuple):
    """One status (``docs/table-controller.md``); ``faults`` the bit mask (:func:`fault_names`)."""

    t_ns: int
    state: str
    buffer_depth: int
    last_chunk_seq: int
    underruns: int
    faults: int
    refused_commands: int
    pose: np.ndarray
    buffer_capacity: int = 0
    """Setpoint samples the controller's buffer holds (0: not reported)."""
    samples_late: int = 0
    """Setpoint samples that arrived after they were due (skipped), since power-up."""
    virtual_watchdog_ms: int = 0
    """0: the controller keeps real time; nonzero: it runs in virtual time and this is its own link watchdog [ms,
    host time], the silence the host allows it instead of its link timeout (as SHAKETABLE_STATUS's field)."""
    inputs: int = 0
    """The interlock inputs set now (bit 0: the enclosure door open; :data:`INPUTS`)."""
    following_error: np.ndarray | None = None
    """Each leg's commanded minus measured length (6,) [m], legs 1…6 (None: not reported)."""


class AccelSamples(NamedTuple):
    """Batch ``seq`` of accelerometer ``sensor_id``: ``samples`` (n, 3), row k at ``t_start_ns + k * spacing_ns``."""

    sensor_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray


class TiltSamples(NamedTuple):
    """Batch ``seq`` of body ``body_id``'s tilt sensor: ``angles`` (n,) [rad], sample k at ``t_start_ns + k *
    spacing_ns``."""

    body_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    angles: np.ndarray


class Refusal(NamedTuple):
    """Setpoint chunk ``seq``, arrived at ``t_ns`` [ns, controller time], refused for ``reason``."""

    t_ns: int
    seq: int
    reason: str


class LimitTripReport(NamedTuple):
    """A level downloaded with ``set_limit`` tripped on ``sensor``'s sample ``value`` [SI] at ``t_ns`` [ns,
    controller time] (``sensor``: the accelerometer, the leg 1–6 or 0); ``code`` and ``level`` [SI] the level's
    ``set_limit`` parameters (``analysis.table.controller_limits``)."""

    t_ns: int
    sensor: int
    code: int
    value: float
    level: float


class OwnerReport(NamedTuple):
    """Command ``cmd_id`` refused: ``owner`` (described) owns the table since ``since_ms`` [ms since the Unix epoch,
    the controller's wall clock], last heard ``silent_ms`` [ms] ago; its claim lapses after ``timeout_ms`` [ms] of
    silence."""

    cmd_id: int
    since_ms: int
    silent_ms: int
    timeout_ms: int
    owner: str


class Overturn(NamedTuple):
    """Overturn event ``event_id`` of body ``body_id``: ``direction`` ±1, plate ``tilt`` [rad] at ``t_ns``."""

    event_id: int
    body_id: int
    direction: int
    tilt: float
    t_ns: int


# ----- URL ----------------------------------------------------------------------------------------------------


def parse_table_url(url: str, *, any_port: bool = False) -> TableUrl:
    """The parts of ``zenoh://HOST:PORT[/TABLE]``; HOST an IP address, PORT 1..65535 (0 too with ``any_port``: the
    listener picks one); :class:`ValueError` otherwise. Whether the address may be used without TLS is judged where
    the endpoint is made (:meth:`TableUrl.endpoint_for`)."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if (parts.scheme != "zenoh" or port is None or not parts.hostname or parts.query or parts.fragment
            or (port == 0 and not any_port)):
        raise ValueError(f"table URL {url!r}: expected zenoh://HOST:PORT/TABLE"
                         + (" (port 0: any free port)" if any_port else ""))
    try:
        host = str(ipaddress.ip_address(parts.hostname))
    except ValueError:
        raise ValueError(f"table URL {url!r}: HOST must be an IP address (e.g. 127.0.0.1, 10.231.0.2, ::1)") from None
    return TableUrl(host, port, check_name(parts.path.strip("/") or DEFAULT_TABLE, "table name"))


# ----- header -------------------------------------------------------------------------------------------------


def _header(kind: TableKind) -> bytes:
    return _HEADER.pack(MAGIC, VERSION, kind)


def _body(payload: bytes, kind: TableKind) -> bytes:
    data = bytes(payload)
    if len(data) < _HEADER.size:
        raise PayloadError(f"payload truncated: {len(data)} bytes, the header alone has {_HEADER.size}")
    magic, version, found = _HEADER.unpack_from(data)
    if magic != MAGIC:
        raise PayloadError(f"not a table link payload: magic {magic!r}, expected {MAGIC!r}")
    if version != VERSION:
        raise PayloadError(f"table link payload version {version} is not supported (this reader knows {VERSION})")
    if found != kind:
        try:
            name = TableKind(found).name
        except ValueError:
            name = f"unknown kind {found}"
        raise PayloadError(f"expected a {kind.name} payload, got {name}")
    return data[_HEADER.size:]


def _fixed(payload: bytes, kind: TableKind, layout: struct.Struct) -> tuple:
    body = _body(payload, kind)
    if len(body) != layout.size:
        raise PayloadError(f"{kind.name} body has {len(body)} bytes, expected {layout.size}")
    return layout.unpack(body)


def _signed(payload: bytes, kind: TableKind, size: int) -> Received:
    """Split a payload whose unsigned body has ``size`` bytes into message and signature trailer."""
    length = _HEADER.size + size
    if len(payload) not in (length, length + TRAILER_BYTES):
        raise PayloadError(f"{kind.name} payload has {len(payload)} bytes, expected {length} (unsigned) or "
                           f"{length + TRAILER_BYTES} (signed)")
    return Received(bytes(payload[:length]), bytes(payload[length:]))


def _code(names: tuple[str, ...], name: str, what: str) -> int:
    if name not in names:
        raise PayloadError(f"unknown {what} {name!r}; expected one of {', '.join(names)}")
    return names.index(name)


def _name(names: tuple[str, ...], code: int, what: str) -> str:
    if code >= len(names):
        raise PayloadError(f"unknown {what} code {code}")
    return names[code]


INPUTS = ("door_open",)
"""The interlock inputs of a status's ``inputs`` mask, bit k named by entry k."""


def input_names(mask: int) -> tuple[str, ...]:
    """The interlock inputs set in ``mask`` (:data:`INPUTS`)."""
    return tuple(name for bit, name in enumerate(INPUTS) if mask >> bit & 1)


def fault_names(mask: int) -> tuple[str, ...]:
    """Names of the fault bits set in ``mask``, in bit order."""
    return tuple(name for bit, name in enumerate(FAULTS) if mask >> bit & 1)


# ----- payloads -----------------------------------------------------------------------------------------------


def encode_command(request: CommandRequest) -> bytes:
    """The unsigned COMMAND payload (sign it with :meth:`protocols.zenoh.auth.Signer.sign`)."""
    code = _code(COMMANDS, request.command, "command")
    return _header(TableKind.COMMAND) + _COMMAND.pack(request.cmd_id, code, *request.params)


def decode_command(payload: bytes) -> tuple[CommandRequest, Received]:
    """The command and the payload split for :meth:`protocols.zenoh.auth.Verifier.verify`."""
    _body(payload, TableKind.COMMAND)
    received = _signed(payload, TableKind.COMMAND, _COMMAND.size)
    cmd_id, code, *params = _COMMAND.unpack_from(received.message, _HEADER.size)
    return CommandRequest(cmd_id, _name(COMMANDS, code, "command"), (params[0], params[1])), received


def encode_answer(answer: Answer) -> bytes:
    return _header(TableKind.ANSWER) + _ANSWER.pack(answer.cmd_id, _code(RESULTS, answer.result, "result"),
                                                    answer.t_ns)


def decode_answer(payload: bytes) -> Answer:
    cmd_id, code, t_ns = _fixed(payload, TableKind.ANSWER, _ANSWER)
    return Answer(cmd_id, _name(RESULTS, code, "result"), t_ns)


def encode_bodies(bodies: list[tuple[float, float, float, float, float]]) -> bytes:
    """The BODIES payload: each body's (b, h, depth, x, y) [m], in body-id order."""
    return _header(TableKind.BODIES) + _COUNT.pack(len(bodies)) + b"".join(_BODY.pack(*b) for b in bodies)


def decode_bodies(payload: bytes) -> list[tuple[float, float, float, float, float]]:
    """Each body's (b, h, depth, x, y) [m] of a BODIES payload, in body-id order."""
    body = _body(payload, TableKind.BODIES)
    if len(body) < _COUNT.size:
        raise PayloadError(f"BODIES body has {len(body)} bytes, expected at least {_COUNT.size}")
    (n,) = _COUNT.unpack_from(body)
    if len(body) != _COUNT.size + n * _BODY.size:
        raise PayloadError(f"BODIES body has {len(body)} bytes, expected {_COUNT.size + n * _BODY.size} for {n} bodies")
    return [_BODY.unpack_from(body, _COUNT.size + k * _BODY.size) for k in range(n)]


def encode_clock_request(t_send_ns: int) -> bytes:
    return _header(TableKind.CLOCK_REQUEST) + _CLOCK_REQUEST.pack(t_send_ns)


def decode_clock_request(payload: bytes) -> int:
    """The host time [ns] the request was sent."""
    (t_send,) = _fixed(payload, TableKind.CLOCK_REQUEST, _CLOCK_REQUEST)
    return t_send


def encode_clock_reply(reply: ClockReply) -> bytes:
    return _header(TableKind.CLOCK_REPLY) + _CLOCK_REPLY.pack(*reply)


def decode_clock_reply(payload: bytes) -> ClockReply:
    return ClockReply(*_fixed(payload, TableKind.CLOCK_REPLY, _CLOCK_REPLY))


def encode_setpoints(chunk: SetpointChunk) -> bytes:
    """The unsigned SETPOINTS payload (sign it with :meth:`protocols.zenoh.auth.Signer.sign`)."""
    samples = np.asarray(chunk.samples, dtype="<f8")
    if samples.ndim != 2 or samples.shape[1] != 6 or not 1 <= len(samples) <= MAX_SAMPLES:
        raise PayloadError(f"setpoint samples must have shape (n, 6) with 1 <= n <= {MAX_SAMPLES}, "
                           f"got {samples.shape}")
    if not np.isfinite(samples).all() or chunk.spacing_ns <= 0:
        raise PayloadError("setpoint samples must be finite and their spacing > 0")
    flags = END_OF_STREAM if chunk.end_of_stream else 0
    return (_header(TableKind.SETPOINTS) + _SETPOINTS.pack(chunk.seq, flags, chunk.t_start_ns, chunk.spacing_ns,
                                                           len(samples)) + samples.tobytes())


def decode_setpoints(payload: bytes) -> tuple[SetpointChunk, Received]:
    """The chunk and the payload split for :meth:`protocols.zenoh.auth.Verifier.verify`."""
    body = _body(payload, TableKind.SETPOINTS)
    if len(body) < _SETPOINTS.size:
        raise PayloadError(f"SETPOINTS body has {len(body)} bytes, its fixed part alone {_SETPOINTS.size}")
    seq, flags, t_start, spacing, n = _SETPOINTS.unpack_from(body)
    if not 1 <= n <= MAX_SAMPLES or spacing <= 0:
        raise PayloadError(f"SETPOINTS with {n} samples (1..{MAX_SAMPLES}) spaced {spacing} ns (> 0)")
    received = _signed(payload, TableKind.SETPOINTS, _SETPOINTS.size + 48 * n)
    samples = np.frombuffer(received.message, dtype="<f8", count=6 * n,
                            offset=_HEADER.size + _SETPOINTS.size).reshape(n, 6).astype(np.float64)
    return SetpointChunk(seq, t_start, spacing, samples, bool(flags & END_OF_STREAM)), received


def encode_status(status: StatusReport) -> bytes:
    return _header(TableKind.STATUS) + _STATUS.pack(
        status.t_ns, _code(STATES, status.state, "state"), status.buffer_depth, status.last_chunk_seq,
        status.underruns, status.faults, status.refused_commands, *np.asarray(status.pose, dtype=np.float64),
        status.buffer_capacity, status.samples_late, status.virtual_watchdog_ms, status.inputs,
        *(np.zeros(6) if status.following_error is None else np.asarray(status.following_error, dtype=np.float64)))


def decode_status(payload: bytes) -> StatusReport:
    """A STATUS; a shorter body without the legs' ``following_error`` reads None there, one also without ``inputs``
    (or also without ``virtual_watchdog_ms``: a real-time controller's without inputs) 0 there."""
    size = len(_body(payload, TableKind.STATUS))
    layout = next((s for s in (_STATUS_REAL_TIME, _STATUS_NO_INPUTS, _STATUS_NO_LEGS) if size == s.size), _STATUS)
    fields = _fixed(payload, TableKind.STATUS, layout)
    t_ns, state, depth, last, underruns, faults, refused, *pose, capacity, late = fields[:15]
    watchdog_ms, inputs = (*fields[15:17], 0, 0)[:2]
    following = np.array(fields[17:], dtype=np.float64) if layout is _STATUS else None
    return StatusReport(t_ns, _name(STATES, state, "state"), depth, last, underruns, faults, refused,
                        np.array(pose, dtype=np.float64), capacity, late, watchdog_ms, inputs, following)


def encode_accel(batch: AccelSamples) -> bytes:
    return _encode_samples(TableKind.ACCEL, _ACCEL, batch.sensor_id, batch, batch.samples, (3,),
                           "accelerometer samples must have shape (n, 3)")


def decode_accel(payload: bytes) -> AccelSamples:
    return AccelSamples(*_decode_samples(payload, TableKind.ACCEL, _ACCEL, (3,)))


def encode_tilt(batch: TiltSamples) -> bytes:
    return _encode_samples(TableKind.TILT, _TILT, batch.body_id, batch, batch.angles, (),
                           "tilt samples must have shape (n,)")


def decode_tilt(payload: bytes) -> TiltSamples:
    return TiltSamples(*_decode_samples(payload, TableKind.TILT, _TILT, ()))


def _encode_samples(kind: TableKind, fixed: struct.Struct, source: int, batch: AccelSamples | TiltSamples,
                    samples: np.ndarray, row: tuple[int, ...], expected: str) -> bytes:
    """A sample batch of ``source``: ``fixed`` (source, seq, t_start, spacing, n), then n rows of shape ``row`` as
    f64; ``expected`` says the shape in the error."""
    values = np.asarray(samples, dtype="<f8")
    if values.shape[1:] != row or values.ndim != 1 + len(row):
        raise PayloadError(f"{expected}, got {values.shape}")
    return _header(kind) + fixed.pack(source, batch.seq, batch.t_start_ns, batch.spacing_ns,
                                      len(values)) + values.tobytes()


def _decode_samples(payload: bytes, kind: TableKind, fixed: struct.Struct, row: tuple[int, ...]
                    ) -> tuple[int, int, int, int, np.ndarray]:
    """(source, seq, t_start, spacing, samples (n, *row)) of a batch written by :func:`_encode_samples`."""
    body = _body(payload, kind)
    if len(body) < fixed.size:
        raise PayloadError(f"{kind.name} body has {len(body)} bytes, its fixed part alone {fixed.size}")
    source, seq, t_start, spacing, n = fixed.unpack_from(body)
    width = math.prod(row)
    if len(body) != fixed.size + 8 * width * n:
        raise PayloadError(f"{kind.name} body has {len(body)} bytes, {n} samples need {fixed.size + 8 * width * n}")
    samples = np.frombuffer(body, dtype="<f8", count=width * n, offset=fixed.size).reshape(n, *row)
    return source, seq, t_start, spacing, samples.astype(np.float64)


def encode_overturn(event: Overturn) -> bytes:
    return _header(TableKind.OVERTURN) + _OVERTURN.pack(*event)


def decode_overturn(payload: bytes) -> Overturn:
    event = Overturn(*_fixed(payload, TableKind.OVERTURN, _OVERTURN))
    if event.direction not in (-1, 1):
        raise PayloadError(f"OVERTURN direction must be +1 or -1, got {event.direction}")
    return event


def encode_limit_trip(trip: LimitTripReport) -> bytes:
    return _header(TableKind.LIMIT_TRIP) + _LIMIT_TRIP.pack(*trip)


def decode_limit_trip(payload: bytes) -> LimitTripReport:
    return LimitTripReport(*_fixed(payload, TableKind.LIMIT_TRIP, _LIMIT_TRIP))


def encode_refusal(refusal: Refusal) -> bytes:
    """The REFUSAL payload (the reason cut to :data:`MAX_REASON` bytes at a character's end)."""
    text = refusal.reason.encode("utf-8")[:MAX_REASON].decode("utf-8", "ignore").encode("utf-8")
    return _header(TableKind.REFUSAL) + _REFUSAL.pack(refusal.t_ns, refusal.seq, len(text)) + text


def decode_refusal(payload: bytes) -> Refusal:
    body = _body(payload, TableKind.REFUSAL)
    if len(body) < _REFUSAL.size:
        raise PayloadError(f"REFUSAL body has {len(body)} bytes, its fixed part alone {_REFUSAL.size}")
    t_ns, seq, n = _REFUSAL.unpack_from(body)
    if n > MAX_REASON or len(body) != _REFUSAL.size + n:
        raise PayloadError(f"REFUSAL body has {len(body)} bytes, a reason of {n} bytes (at most {MAX_REASON}) needs "
                           f"{_REFUSAL.size + n}")
    try:
        reason = body[_REFUSAL.size:].decode("utf-8")
    except UnicodeDecodeError:
        raise PayloadError("REFUSAL reason is not UTF-8") from None
    return Refusal(t_ns, seq, reason)


def encode_owner(report: OwnerReport) -> bytes:
    """The OWNER payload (the owner's description cut to :data:`MAX_REASON` bytes at a character's end)."""
    text = report.owner.encode("utf-8")[:MAX_REASON].decode("utf-8", "ignore").encode("utf-8")
    return _header(TableKind.OWNER) + _OWNER.pack(report.cmd_id, report.since_ms, report.silent_ms,
                                                  report.timeout_ms, len(text)) + text


def decode_owner(payload: bytes) -> OwnerReport:
    body = _body(payload, TableKind.OWNER)
    if len(body) < _OWNER.size:
        raise PayloadError(f"OWNER body has {len(body)} bytes, its fixed part alone {_OWNER.size}")
    cmd_id, since_ms, silent_ms, timeout_ms, n = _OWNER.unpack_from(body)
    if n > MAX_REASON or len(body) != _OWNER.size + n:
        raise PayloadError(f"OWNER body has {len(body)} bytes, an owner of {n} bytes (at most {MAX_REASON}) needs "
                           f"{_OWNER.size + n}")
    try:
        owner = body[_OWNER.size:].decode("utf-8")
    except UnicodeDecodeError:
        raise PayloadError("OWNER description is not UTF-8") from None
    return OwnerReport(cmd_id, since_ms, silent_ms, timeout_ms, owner)


def encode_heartbeat(t_ns: int) -> bytes:
    return _header(TableKind.HEARTBEAT) + _HEARTBEAT.pack(t_ns)


def decode_heartbeat(payload: bytes) -> int:
    """The sender's time [ns] in a HEARTBEAT."""
    (t_ns,) = _fixed(payload, TableKind.HEARTBEAT, _HEARTBEAT)
    return t_ns
