"""Authentication of the table link over zenoh: HMAC-SHA256 signatures on every payload of the link.

zenoh has nothing like MAVLink 2 signing, so the table link signs its payloads itself, with the rig's 32-byte key
(``protocols.mavlink.load_signing_key``: a key file or ``$SHAKETABLE_MAVLINK_KEY``). A signed payload is the
payload as it would travel unsigned (header and body, :mod:`protocols.zenoh.table`) followed by a 48-byte trailer::

    offset       size  field
    0            m     message: the unsigned payload (8-byte header + body)
    m            8     sender (UNSIGNED64, little-endian): random per sending connection (:class:`Signer`)
    m + 8        8     stamp (UNSIGNED64): µs since 1970-01-01 UTC, strictly increasing per sender
    m + 16       32    tag = HMAC-SHA256(key, key expression (UTF-8) ‖ 0x00 ‖ message ‖ sender ‖ stamp)

The key expression the payload travels on is inside the tag, so a signed chunk is worthless on another table's
keys or as a command. A receiver (:class:`Verifier`) takes a payload as **signed** only when the tag verifies
(constant-time comparison) and the stamp is fresh: above the last stamp it accepted from that sender on that key
expression, and for a sender it has not heard on that key, at most :data:`FRESHNESS` behind its own wall clock.
Replayed, reordered and stale payloads therefore count as unsigned, as in MAVLink signing. Only a payload whose
tag verified moves the sender's stamp: a forged one with a future stamp cannot lock the real sender out. A
receiver that restarted accepts, once, only a payload recorded less than :data:`FRESHNESS` (a few seconds) before
from a sender it has not heard since; host and controller clocks must agree within that.

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
from collections import OrderedDict
from typing import NamedTuple

KEY_BYTES = 32
"""Length of the rig's key."""

TAG_BYTES = 32
"""Length of an HMAC-SHA256 tag."""

_TRAILER = struct.Struct("<QQ")  # sender, stamp

TRAILER_BYTES = _TRAILER.size + TAG_BYTES
"""Length of a signature's trailer: sender, stamp, tag."""

FRESHNESS = 5.0
"""How far behind the receiver's wall clock the first stamp of a sender may be [s] (MAVLink's
``protocols.mavlink.REPLAY_WINDOW``)."""

_HEADER_BYTES = 8  # the table link's payload header (protocols.zenoh.table)

REMEMBERED_SENDERS = 1024
"""(sender, key expression) pairs whose last stamp a :class:`Verifier` remembers (the least recent is forgotten)."""


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


class Signer:
    """Signs payloads as one sender (module docstring); ``sender`` a 64-bit id, random per connection. Thread-safe:
    stamps increase in the order of the calls."""

    def __init__(self, key: bytes, sender: int) -> None:
        self._key = _check_key(key)
        if not 0 <= sender < 2**64:
            raise ValueError(f"sender must be a 64-bit unsigned integer, got {sender}")
        self.sender = sender
        self._stamp = 0
        self._lock = threading.Lock()

    def sign(self, key_expr: str, message: bytes) -> bytes:
        """``message`` with its trailer, for the key expression ``key_expr`` it will travel on."""
        with self._lock:
            self._stamp = max(self._stamp + 1, time.time_ns() // 1000)
            stamp = self._stamp
        covered = bytes(message) + _TRAILER.pack(self.sender, stamp)
        return covered + _tag(self._key, key_expr, covered)


class Verifier:
    """Checks signatures (module docstring) and remembers each sender's last stamp per key expression. Not thread-safe:
    verify a key expression's payloads from one thread, in the order they arrived."""

    def __init__(self, key: bytes) -> None:
        self._key = _check_key(key)
        self._last: OrderedDict[tuple[int, str], int] = OrderedDict()

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
        signature stamped at most :data:`FRESHNESS` behind the wall clock. Replies to different queries may arrive
        in any order, so their stamps are not ordered; the caller matches the reply to its query (a command id, a
        clock request's send time), which a replayed reply does not."""
        verdict = self._tag_verdict(key_expr, received)
        if verdict is not Verdict.SIGNED:
            return verdict
        stamp = _TRAILER.unpack_from(received.trailer)[1]
        return Verdict.STALE if stamp < time.time_ns() // 1000 - round(FRESHNESS * 1e6) else Verdict.SIGNED

    def verify(self, key_expr: str, received: Received) -> Verdict:
        """Whether ``received`` came on ``key_expr`` with a valid, fresh signature; a signed one moves the stamp."""
        verdict = self._tag_verdict(key_expr, received)
        if verdict is not Verdict.SIGNED:
            return verdict
        sender, stamp = _TRAILER.unpack_from(received.trailer)
        last = self._last.get((sender, key_expr))
        if last is None:
            last = time.time_ns() // 1000 - round(FRESHNESS * 1e6) - 1
        if stamp <= last:
            return Verdict.STALE
        self._last[(sender, key_expr)] = stamp
        self._last.move_to_end((sender, key_expr))
        if len(self._last) > REMEMBERED_SENDERS:
            self._last.popitem(last=False)
        return Verdict.SIGNED
