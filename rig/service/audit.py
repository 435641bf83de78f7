"""Who sent a control request, as the service writes it in the session's events: taken from the transport, never
from what the request says about itself, and escaped so that one request is one line.

* A request **signed** with the rig's key (:mod:`protocols.zenoh.auth`: the console, ``rig service …`` and
  ``rig run --service`` with the key) is named by its signature's sender (random per client connection) and, if it
  carries one, by its ``source`` argument: only a holder of the rig's key can have written that text.
* An **unsigned** request (``pause``, ``abort`` and ``estop`` are accepted from anyone: stopping never waits for a
  key) is an ``unsigned zenoh client``; a ``source`` it gives is not written (anyone can claim to be the console).
* Every text written (the source, the service's message) is escaped: control and format characters (newlines, the
  Unicode line separators, bidi overrides) as ``\\xNN``/``\\uNNNN``, the backslash doubled, cut at
  :data:`MAX_TEXT` characters.
"""

from __future__ import annotations

import struct
import unicodedata

from protocols.zenoh.auth import Verdict

MAX_TEXT = 200
"""Longest source or message written [characters] (longer: cut, with "…")."""


def escaped(text: str, limit: int = MAX_TEXT) -> str:
    """``text`` on one line (module docstring)."""
    out = []
    for char in text[:limit]:
        if char == "\\":
            out.append("\\\\")
        elif unicodedata.category(char)[0] == "C" or char in "\u2028\u2029":
            out.append(f"\\x{ord(char):02x}" if ord(char) < 0x100 else f"\\u{ord(char):04x}")
        else:
            out.append(char)
    return "".join(out) + ("…" if len(text) > limit else "")


def sender_of(attachment: bytes | None) -> int | None:
    """The sender field of a signature trailer (the attachment of a signed request), or None."""
    if attachment is None or len(attachment) < 8:
        return None
    return int(struct.unpack_from("<Q", attachment)[0])


def request_source(claimed: object, verdict: Verdict | None, attachment: bytes | None) -> str:
    """Who sent a request whose args claim ``claimed`` as source, given its signature's ``verdict`` (None: the
    service checks no signatures, ``--no-auth``) and attachment (module docstring)."""
    if verdict is Verdict.SIGNED:
        who = f"rig key holder {sender_of(attachment):016x}"
        return f"{escaped(claimed)} (signed: {who})" if isinstance(claimed, str) and claimed else who
    if verdict is None:
        return "zenoh client (signatures not checked: --no-auth)"
    if verdict is Verdict.UNSIGNED:
        return "unsigned zenoh client"
    kind = {Verdict.STALE: "stale", Verdict.FUTURE: "future-stamped"}.get(verdict, "bad")
    return f"zenoh client with a {kind} signature"
