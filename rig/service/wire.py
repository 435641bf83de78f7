"""What travels on the service's keys: CONTROL_REQUEST / CONTROL_REPLY / STATUS / RUN payloads of
:mod:`protocols.zenoh.payloads`, the signature of a motion-causing request, and the service's errors.

A request is ``{"command": <the key's last chunk>, "args": {...}}``. A signed request (``start``, ``resume``) carries
the signature trailer of :mod:`protocols.zenoh.auth` (sender, stamp, HMAC-SHA256 tag over the key expression and
the whole payload) as the zenoh query's **attachment**: the payload itself stays a plain CONTROL_REQUEST.

A reply is ``{"ok": bool, "state": <orchestrator state>, "message": str, ...}``: ``ok`` false is a refusal with the
reason in ``message`` (a bad sequence: its ``FILE:LINE: key: problem``). Extra fields: ``session`` (the session
file's path or null), ``active`` (a session is being prepared or played), ``progress``
(:meth:`rig.orchestrator.Progress.as_dict`, non-finite numbers as null) and ``seq``. STATUS telemetry carries the
same fields plus ``t_ns`` (host wall clock [ns]); its ``seq`` counts up by one per STATUS publication of the
service's lifetime, and a reply's ``seq`` is that of the last STATUS published before it.
"""

from __future__ import annotations

from typing import Any

from protocols.zenoh.auth import Received, Signer, Verdict, Verifier
from protocols.zenoh.payloads import Kind, decode_json, encode_json


class ServiceError(Exception):
    """The service refused a command (the message is its reply's, ``reply`` the whole reply), or its answer could
    not be read (``reply`` None)."""

    def __init__(self, message: str, reply: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.reply = reply


class ServiceUnavailableError(ServiceError):
    """No rig service answers at the endpoint."""


def encode_request(command: str, args: dict[str, Any]) -> bytes:
    """The CONTROL_REQUEST payload of ``command``."""
    return encode_json(Kind.CONTROL_REQUEST, {"command": command, "args": args})


def decode_request(payload: bytes) -> tuple[str, dict[str, Any]]:
    """``(command, args)`` of a CONTROL_REQUEST payload (:class:`~protocols.zenoh.payloads.PayloadError`)."""
    body = decode_json(payload, Kind.CONTROL_REQUEST)
    return body["command"], body["args"]


def encode_reply(ok: bool, state: str, message: str, **extra: Any) -> bytes:
    """The CONTROL_REPLY payload."""
    return encode_json(Kind.CONTROL_REPLY, {"ok": ok, "state": state, "message": message, **extra})


def decode_reply(payload: bytes) -> dict[str, Any]:
    """The body of a CONTROL_REPLY payload."""
    return decode_json(payload, Kind.CONTROL_REPLY)


def sign(signer: Signer, key_expr: str, payload: bytes) -> bytes:
    """The attachment that signs ``payload`` sent on ``key_expr``: the signature trailer alone."""
    return signer.sign(key_expr, payload)[len(payload):]


REFUSALS = {
    Verdict.UNSIGNED: "not signed: commands that move the table must be signed with the rig's key (give the "
                      "client --key-file or set $SHAKETABLE_MAVLINK_KEY)",
    Verdict.BAD_SIGNATURE: "bad signature (not the service's rig key, or altered on the way)",
    Verdict.STALE: "stale signature (replayed, reordered, or the client's clock is more than 5 s behind)",
    Verdict.FUTURE: "signature stamped in the future (the client's clock is more than 5 s ahead of the service's)",
}
"""Why a signed command was refused, by the verifier's verdict."""


def verify(verifier: Verifier, key_expr: str, payload: bytes, attachment: bytes | None) -> Verdict:
    """The verdict on a request received on ``key_expr`` with its attachment (None: unsigned)."""
    return verifier.verify(key_expr, Received(bytes(payload), bytes(attachment or b"")))
