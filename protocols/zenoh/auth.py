"""Authentication of the table link over zenoh: HMAC-SHA256 signatures on every payload of the link.

zenoh has nothing like MAVLink 2 signing, so the table link signs its payloads itself, with the rig's 32-byte key
(``protocols.signing_key.load_signing_key``: a key file or ``$SHAKETABLE_MAVLINK_KEY``). A signed payload is the
payload as it would travel unsigned (header and body, :mod:`protocols.zenoh.table`) followed by a 48-byte trailer::

    offset       size  field
    0            m     message: the unsigned payload (8-byte header + body)
    m            8     sender (UNSIGNED64, little-endian): random per sending connection (:class:`Signer`)
    m + 8        8     stamp (UNSIGNED64): µs since 1970-01-01 UTC, strictly increasing per sender
    m + 16       32    tag = HMAC-SHA256(key, key expression (UTF-8) ‖ 0x00 ‖ message ‖ sender ‖ stamp)

The key expression the payload travels on is inside the tag, so a signed chunk is worthless on another table's
keys or as a command. A receiver (:class:`Verifier`) takes a payload as **signed** only when the tag verifies
(constant-time comparison) and its :class:`~protocols.replay.ReplayGuard` finds the stamp fresh, by MAVLink's
rules (:mod:`protocols.replay`; a stream is a sender on a key expression): above the last stamp it accepted from
that sender on that key expression; for a sender it has not heard there, at most :data:`FRESHNESS` behind its
current stamp (the largest of its wall clock, the stamps it has taken and those a controller restored at start);
and never more than :data:`STAMP_AHEAD` beyond it. Replayed, reordered, stale and future payloads therefore count
as unsigned, as in MAVLink signing. Only a payload whose tag verified moves the guard: a forged one with a future
stamp cannot lock the real sender out. A controller keeps its guard's state across restarts
(``sim_table.replay_store``), so a capture replayed after a restart is refused whatever its clock says.

The host signs its commands, setpoint chunks and heartbeats; the controller signs everything it sends (statuses,
answers, clock replies, accelerometer and tilt batches, overturn events, heartbeats), each copy of a resent
message afresh. :func:`split_signed` cuts the trailer off a payload whose kind always carries one.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import struct
import threading
import time
from collections.abc import Callable
from typing import NamedTuple

from protocols.replay import Freshness, ReplayGuard, ReplayState

KEY_BYTES = 32
"""Length of the rig's key."""

TAG_BYTES = 32
"""Length of an HMAC-SHA256 tag."""

_TRAILER = struct.Struct("<QQ")  # sender, stamp

TRAILER_BYTES = _TRAILER.size + TAG_BYTES
"""Length of a signature's trailer: sender, stamp, tag."""

FRESHNESS = 5.0
"""How far behind the receiver's current stamp the first stamp of a sender may be [s] (MAVLink's
``protocols.mavlink.REPLAY_WINDOW``)."""

STAMP_AHEAD = 5.0
"""How far beyond the receiver's current stamp a stamp may be [s] (MAVLink's ``protocols.mavlink.STAMP_AHEAD``)."""

_HEADER_BYTES = 8  # the table link's payload header (protocols.zenoh.table)

class Received(NamedTuple):
    """A received payload split into the ``message`` (header and body) and its ``trailer`` (empty: unsigned)."""

    message: bytes
    trailer: bytes


class Verdict(enum.Enum):
    """What :meth:`Verifier.verify` found."""

    SIGNED = "signed"
    UNSIGNED = "unsigned"  # no trailer
    BAD_SIGNATURE = "bad_signature"  # another key, another key expression, or altered
    STALE = "stale"  # a stamp not above the sender's last one (replayed, reordered) or too old
    FUTURE = "future"  # a stamp too far ahead of the receiver's current stamp


def split_signed(payload: bytes) -> Received:
    """``payload`` split into message and trailer for a kind that is always signed: the trailer is its last
    :data:`TRAILER_BYTES` bytes; a payload too short to hold a header and a trailer is unsigned (empty trailer). An
    unsigned payload long enough is cut all the same and its "signature" does not verify."""
    if len(payload) < _HEADER_BYTES + TRAILER_BYTES:
        return Received(bytes(payload), b"")
    return Received(bytes(payload[:-TRAILER_BYTES]), bytes(payload[-TRAILER_BYTES:]))


def sender_of(received: Received) -> int | None:
    """The sender id in ``received``'s trailer (None: unsigned or malformed); meaningful once verified."""
    if len(received.trailer) != TRAILER_BYTES:
        return None
    return _TRAILER.unpack_from(received.trailer)[0]


def _check_key(key: bytes) -> bytes:
    if len(key) != KEY_BYTES:
        raise ValueError(f"a table link key has {KEY_BYTES} bytes, got {len(key)}")
    return bytes(key)


def _tag(key: bytes, key_expr: str, covered: bytes) -> bytes:
    return hmac.new(key, key_expr.encode() + b"\0" + covered, hashlib.sha256).digest()


def wall_stamp() -> int:
    """The wall clock as a stamp [µs since 1970-01-01 UTC]."""
    return time.time_ns() // 1000


def replay_guard(state: ReplayState | None = None) -> ReplayGuard:
    """A receiver's :class:`~protocols.replay.ReplayGuard` for this link's stamps (µs since 1970; streams: sender
    id and key expression), from ``state`` if it was kept."""
    return ReplayGuard(wall_stamp, round(FRESHNESS * 1e6), round(STAMP_AHEAD * 1e6), state=state)


class Signer:
    """Signs payloads as one sender (module docstring); ``sender`` a 64-bit id, random per connection; ``clock()``
    the stamp it never signs below [µs since 1970] (default the wall clock; a controller gives its guard's current
    stamp, :meth:`~protocols.replay.ReplayGuard.current`). Thread-safe: stamps increase in the order of the calls."""

    def __init__(self, key: bytes, sender: int, clock: Callable[[], int] = wall_stamp) -> None:
        self._key = _check_key(key)
        if not 0 <= sender < 2**64:
            raise ValueError(f"sender must be a 64-bit unsigned integer, got {sender}")
        self.sender = sender
        self._clock = clock
        self._stamp = 0
        self._lock = threading.Lock()

    def sign(self, key_expr: str, message: bytes) -> bytes:
        """``message`` with its trailer, for the key expression ``key_expr`` it will travel on."""
        with self._lock:
            self._stamp = max(self._stamp + 1, self._clock())
            stamp = self._stamp
        covered = bytes(message) + _TRAILER.pack(self.sender, stamp)
        return covered + _tag(self._key, key_expr, covered)


class Verifier:
    """Checks signatures (module docstring); ``guard`` (default: a new one, :func:`replay_guard`) keeps each sender's
    last stamp per key expression. Verify a key expression's payloads from one thread, in the order they arrived."""

    def __init__(self, key: bytes, guard: ReplayGuard | None = None) -> None:
        self._key = _check_key(key)
        self.guard = guard if guard is not None else replay_guard()

    def _tag_verdict(self, key_expr: str, received: Received) -> Verdict:
        if not received.trailer:
            return Verdict.UNSIGNED
        if len(received.trailer) != TRAILER_BYTES:
            return Verdict.BAD_SIGNATURE
        covered = received.message + received.trailer[:_TRAILER.size]
        if not hmac.compare_digest(_tag(self._key, key_expr, covered), received.trailer[_TRAILER.size:]):
            return Verdict.BAD_SIGNATURE
        return Verdict.SIGNED

    def verify_reply(self, key_expr: str, received: Received) -> Verdict:
        """Whether ``received``, a reply to one of this receiver's own queries, came on ``key_expr`` with a valid
        signature stamped at most :data:`FRESHNESS` behind the current stamp and :data:`STAMP_AHEAD` beyond it.
        Replies to different queries may arrive in any order, so their stamps are not ordered; the caller matches the
        reply to its query (a command id, a clock request's send time), which a replayed reply does not."""
        verdict = self._tag_verdict(key_expr, received)
        if verdict is not Verdict.SIGNED:
            return verdict
        stamp = _TRAILER.unpack_from(received.trailer)[1]
        now = self.guard.current()
        if stamp > now + self.guard.ahead:
            return Verdict.FUTURE
        return Verdict.STALE if stamp < now - self.guard.window else Verdict.SIGNED

    def verify(self, key_expr: str, received: Received) -> Verdict:
        """Whether ``received`` came on ``key_expr`` with a valid, fresh signature; a signed one moves the stamp."""
        verdict = self._tag_verdict(key_expr, received)
        if verdict is not Verdict.SIGNED:
            return verdict
        sender, stamp = _TRAILER.unpack_from(received.trailer)
        return _VERDICTS[self.guard.admit((sender, key_expr), stamp)]


_VERDICTS = {Freshness.FRESH: Verdict.SIGNED, Freshness.STALE: Verdict.STALE, Freshness.FUTURE: Verdict.FUTURE}
