"""The operator token: what the console's controls need, derived from the rig's key.

    token = HMAC-SHA256(rig key, b"operator-console"), as 64 hex digits

The rig's key (``--key-file``, else ``$SHAKETABLE_MAVLINK_KEY``) signs the table link and the service's motion
commands; the token is derived from it so that it changes with the key, and it cannot be turned back into the key
(HMAC is one-way). ``rig service token`` prints it for the operator, who gives it once on the page; the page does
not keep it: the console opens a browser session instead (:mod:`rig.console.browsers`). Compared in constant time.
"""

from __future__ import annotations

import hashlib
import hmac
from pathlib import Path

from protocols.signing_key import load_signing_key

TOKEN_CONTEXT = b"operator-console"
"""The HMAC message that derives the operator token from the rig's key."""


def operator_token(key: bytes) -> str:
    """The operator token of the rig key ``key`` (module docstring)."""
    return hmac.new(key, TOKEN_CONTEXT, hashlib.sha256).hexdigest()


def token_from_key_file(key_file: Path | None) -> str:
    """The operator token of the rig's key in ``key_file`` (else ``$SHAKETABLE_MAVLINK_KEY``);
    ``protocols.mavlink.SigningKeyError`` when there is none or it is malformed."""
    return operator_token(load_signing_key(key_file))


def token_matches(expected: str | None, given: str | None) -> bool:
    """``given`` is the operator token (False when the console has none: it is read-only)."""
    if not expected or not given:
        return False
    return hmac.compare_digest(expected.encode(), given.strip().encode())
