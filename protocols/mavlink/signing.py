"""MAVLink 2 message signing for the table link: the rig's key, signing on a link, and which messages need it.

Motion commands are signed (docs/architecture.md §5): the host signs everything it sends; the controller refuses a
message that :func:`requires_signature` unless :func:`signed_with_key` holds for it.

**Key.** The rig's 32-byte secret, read by :func:`protocols.signing_key.load_signing_key` (a key file or
``$SHAKETABLE_MAVLINK_KEY``; what a key must be is said there).

**Receiving.** :func:`enable_signing` installs pymavlink's ``allow_unsigned_callback`` so that unsigned and
badly signed messages are still *delivered*, flagged by ``msg.get_signed() == False``, instead of being raised
as errors by the parser; the policy is applied per message, so that a STOP or an EMERGENCY_STOP is never lost for
want of a signature. pymavlink marks a message signed only when its signature verified with the receiver's key
and its timestamp was newer than the last one of its stream (link id, system, component): replayed or
reordered signed messages count as unsigned.

**Timestamps.** A signature carries a 48-bit timestamp in units of 10 µs since 2015-01-01 00:00:00 UTC; a
sender starts from its wall clock (:func:`signing_timestamp`), pymavlink adds one per message sent, and
:func:`follow_wall_clock` before each send keeps it at or above the receiver side's current stamp (its wall clock,
or more: the largest stamp it has taken), so that a long connection does not fall behind. What a receiver takes is
decided by its :class:`protocols.replay.ReplayGuard` (:func:`replay_guard`: MAVLink's timestamp rules, a new stream
at most :data:`REPLAY_WINDOW` behind the current stamp instead of the specification's minute, no stamp more than
:data:`STAMP_AHEAD` beyond it) before pymavlink parses the frame (:func:`parse_guarded`): a controller that keeps
its guard's state across restarts (``sim_table.replay_store``) refuses a capture replayed after a restart whatever
its clock says, and a message stamped from a clock far ahead is refused.
"""

from __future__ import annotations

import calendar
import functools
import hashlib
import hmac
import time
from typing import Any

from protocols.mavlink.codegen import dialect
from protocols.replay import Freshness, ReplayGuard, ReplayState
from protocols.signing_key import KEY_BYTES, SigningKeyError

SIGNED_FRAME = 0x01
"""MAVLINK_IFLAG_SIGNED, the signed bit of a MAVLink 2 frame's ``incompat_flags`` (its third byte)."""

SIGNING_EPOCH = calendar.timegm((2015, 1, 1, 0, 0, 0))
"""The MAVLink signing epoch, 2015-01-01 00:00:00 UTC, in Unix seconds."""

REPLAY_WINDOW = 5.0
"""How far behind the receiver's current stamp the first signed message of a stream it has not heard may be [s]."""

STAMP_AHEAD = 5.0
"""How far beyond the receiver's current stamp a signed message may be stamped [s]."""

TIMESTAMP_UNITS_PER_S = 100_000
"""Signing timestamp units (10 µs) per second."""


def signing_timestamp(unix_time: float | None = None) -> int:
    """A signing timestamp [10 µs since 2015-01-01 UTC] for ``unix_time`` [s] (default: now)."""
    now = time.time() if unix_time is None else unix_time
    return max(0, int((now - SIGNING_EPOCH) * TIMESTAMP_UNITS_PER_S))


def follow_wall_clock(mav: Any, guard: ReplayGuard | None = None) -> None:
    """Raise the next outgoing signing timestamp of ``mav`` to the wall clock, or to ``guard``'s current stamp (the
    receiving side of the same link), if it fell behind (call before a send, under the lock that serialises
    sends)."""
    mav.signing.timestamp = max(mav.signing.timestamp, guard.current() if guard is not None else signing_timestamp())


def replay_guard(state: ReplayState | None = None) -> ReplayGuard:
    """A receiver's :class:`~protocols.replay.ReplayGuard` for MAVLink signatures (streams: link id, system,
    component; stamps in 10 µs since 2015), from ``state`` if it was kept."""
    return ReplayGuard(signing_timestamp, round(REPLAY_WINDOW * TIMESTAMP_UNITS_PER_S),
                       round(STAMP_AHEAD * TIMESTAMP_UNITS_PER_S), state=state)


def signature_stream(frame: bytes) -> tuple[tuple[int, int, int], int] | None:
    """The stream (link id, system, component) and timestamp [10 µs since 2015] of one signed MAVLink 2 ``frame``;
    None for an unsigned one."""
    if not frame[2] & SIGNED_FRAME:
        return None
    return (frame[-13], frame[5], frame[6]), int.from_bytes(frame[-12:-6], "little")


def signature_matches(key: bytes, frame: bytes) -> bool:
    """Whether the signature of one signed MAVLink 2 ``frame`` is the one ``key`` makes of it (MAVLink 2 signing:
    the first 6 bytes of SHA-256 over the key and the frame up to its signature)."""
    return hmac.compare_digest(hashlib.sha256(key + frame[:-6]).digest()[:6], frame[-6:])


def parse_guarded(mav: Any, guard: ReplayGuard, frame: bytes) -> tuple[list[Any], Freshness | None]:
    """The messages of one MAVLink 2 ``frame`` parsed by ``mav`` (signing enabled), flagged signed only when the
    signature verified and ``guard`` found its stamp fresh, and that freshness (None: an unsigned frame, or one whose
    signature is not the key's: its stamp is nobody's to judge, and the frame counts as badly signed). A signed
    message taken moves its stream in ``guard``; a stale or future one moves nothing (:func:`parse_verified`)."""
    stream = signature_stream(frame)
    key = mav.signing.secret_key
    if stream is not None and key is not None and not signature_matches(key, frame):
        stream = None
    freshness = None if stream is None else guard.check(*stream)
    messages = parse_verified(mav, frame, stale=freshness not in (None, Freshness.FRESH))
    if stream is not None and freshness is Freshness.FRESH and any(msg.get_signed() for msg in messages):
        guard.accept(*stream)
    return messages, freshness


def enable_signing(mav: Any, key: bytes, *, link_id: int, sign_outgoing: bool = True,
                   timestamp: int | None = None) -> None:
    """Sign what ``mav`` (a dialect ``MAVLink`` object) sends and verify what it receives with ``key``.

    ``link_id`` (0–255) names this link in the signatures; give each link of one system its own. ``timestamp``
    [10 µs since 2015-01-01] starts the outgoing timestamps (default: now). Incoming unsigned or badly signed
    messages are delivered unsigned-flagged, not raised (see the module docstring).
    """
    if len(key) != KEY_BYTES:
        raise SigningKeyError(f"a signing key has {KEY_BYTES} bytes, got {len(key)}")
    if not 0 <= link_id <= 255:
        raise ValueError(f"link_id must be in 0..255, got {link_id}")
    mav.signing.secret_key = bytes(key)
    mav.signing.link_id = link_id
    mav.signing.timestamp = signing_timestamp() if timestamp is None else timestamp
    mav.signing.sign_outgoing = sign_outgoing
    mav.signing.allow_unsigned_callback = _deliver_flagged


def _deliver_flagged(mav: Any, msg_id: int) -> bool:
    """pymavlink's unsigned-message callback: deliver every message; ``get_signed()`` tells the truth."""
    return True


def signed_with_key(msg: Any) -> bool:
    """Whether ``msg`` carried a valid, fresh signature made with the key of the ``MAVLink`` that parsed it.

    False for unsigned, badly signed, replayed or reordered messages, and for every message parsed by a
    ``MAVLink`` object without a key (pymavlink then checks nothing).
    """
    return bool(msg.get_signed())


def parse_verified(mav: Any, frame: bytes, *, stale: bool = False) -> list[Any]:
    """The messages of ``frame`` parsed by ``mav`` (signing enabled), BAD_DATA left out, each flagged as
    :func:`signed_with_key` says; ``stale`` (the guard refused the stamp, :func:`parse_guarded`) flags them unsigned
    whatever pymavlink found.
    A badly signed or stale message does not move its stream's timestamp: pymavlink records it before checking the
    signature, so one forged message with a future timestamp would lock the real sender out, and a replayed one
    would open its stream to the rest of the capture; it is restored."""
    stamps = mav.signing.stream_timestamps
    before = dict(stamps)
    messages = []
    for msg in mav.parse_buffer(frame) or []:
        if msg.get_type() == "BAD_DATA":
            continue
        if stale:
            msg._signed = False
        if not msg.get_signed() and msg._header.incompat_flags & SIGNED_FRAME:
            stream = (msg._msgbuf[-13], msg.get_srcSystem(), msg.get_srcComponent())
            if stream in before:
                stamps[stream] = before[stream]
            else:
                stamps.pop(stream, None)
        messages.append(msg)
    return messages


def badly_signed(msg: Any) -> bool:
    """Whether ``msg`` carried a signature that did not verify (another key, altered, replayed or reordered), as
    opposed to none."""
    return not msg.get_signed() and bool(msg._header.incompat_flags & SIGNED_FRAME)


@functools.cache
def stop_commands() -> frozenset[int]:
    """The commands accepted unsigned: DISARM, STOP, EMERGENCY_STOP (stopping is never refused)."""
    d = dialect()
    return frozenset({d.MAV_CMD_SHAKETABLE_DISARM, d.MAV_CMD_SHAKETABLE_STOP, d.MAV_CMD_SHAKETABLE_EMERGENCY_STOP})


def requires_signature(msg: Any) -> bool:
    """Whether the controller must refuse ``msg`` unless :func:`signed_with_key`.

    Every setpoint chunk, and every command (COMMAND_LONG, COMMAND_INT) except those of :func:`stop_commands`;
    other messages (heartbeats, time sync, telemetry) need no signature.
    """
    kind = msg.get_type()
    if kind == "SHAKETABLE_SETPOINT_CHUNK":
        return True
    if kind in ("COMMAND_LONG", "COMMAND_INT"):
        return msg.command not in stop_commands()
    return False
