"""The rig's signing key: the one place a key is read (a key file or ``$SHAKETABLE_MAVLINK_KEY``) and written.

One 32-byte secret shared by the host and the controller signs the table link (MAVLink 2 signing,
:mod:`protocols.mavlink.signing`; zenoh's HMAC, :mod:`protocols.zenoh.auth`), the rig service's commands and the
console's operator token. Every reader of a key calls :func:`load_signing_key`; every writer of a new one
:func:`write_signing_key`.

**What a key must be**: 32 bytes from a cryptographic random source — ``python -c "import secrets;
print(secrets.token_hex(32))"`` or ``openssl rand -hex 32`` — given as 64 hexadecimal digits (surrounding
whitespace allowed) in :envvar:`SHAKETABLE_MAVLINK_KEY` or in a key file, or as exactly 32 raw bytes in a key file.
Refused, each with a one-line :class:`SigningKeyError` naming the source:

- a key file that group or others may access (mode & 0o077, as ssh refuses a private key): the message says the
  ``chmod 600`` to run; a key file that is not a regular file;
- the all-zero key (MAVLink implementations treat it as "no key");
- a key with too little entropy to be random: fewer than :data:`MIN_DISTINCT` distinct byte values among its 32,
  or among the 31 differences of successive bytes (``00…01``, ``abab…``, a repeated or counting pattern). A random
  key fails this with probability below 1e-15;
- 32 raw bytes that are all printable ASCII: a typed password or 32 hexadecimal digits (half a key), not a random
  key (a random raw key is all printable with probability 2e-14).

**A passphrase** (``--key-passphrase``, :func:`key_from_passphrase`): the key is the SHA-256 of the passphrase's
ASCII bytes, as ArduPilot's tools derive it (MAVProxy's ``signing setup PASSPHRASE``, Mission Planner's passkeys), so
that a ground station given the same passphrase signs with the same key. Hashing adds no entropy, so the passphrase
itself must be hard to guess: at least :data:`MIN_PASSPHRASE` printable ASCII characters (what ArduPilot's tools can
type) with at least :data:`MIN_PASSPHRASE_DISTINCT` distinct ones; a shorter or repetitive one is refused saying so.
"""

from __future__ import annotations

import hashlib
import itertools
import os
from collections.abc import Mapping
from pathlib import Path

from protocols.private_file import PrivateFileError, read_private_file

KEY_ENV = "SHAKETABLE_MAVLINK_KEY"
"""Environment variable holding the signing key as 64 hexadecimal digits."""

KEY_BYTES = 32
"""Length of the rig's key [bytes]."""

MIN_DISTINCT = 16
"""Fewest distinct byte values a key must have among its 32 bytes, and among the 31 differences of successive
bytes (module docstring)."""

MIN_PASSPHRASE = 20
"""Fewest characters of a passphrase (e.g. five random words, or 20 random characters)."""

MIN_PASSPHRASE_DISTINCT = 10
"""Fewest distinct characters of a passphrase."""

_MAX_KEY_FILE = 4096  # a key file is 32 or 64-odd bytes: a larger one is not a key file


class SigningKeyError(ValueError):
    """The signing key is missing, unsafe or malformed; the message says where it came from and what is wrong."""


def _parse_hex(text: str, source: str) -> bytes:
    text = text.strip()
    if len(text) != 2 * KEY_BYTES:
        raise SigningKeyError(f"{source}: expected {2 * KEY_BYTES} hexadecimal digits, got {len(text)} characters")
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise SigningKeyError(f"{source}: not hexadecimal") from None


def check_key_strength(key: bytes, source: str) -> bytes:
    """``key`` if it can be a random 32-byte key (module docstring), else :class:`SigningKeyError` naming
    ``source``."""
    if len(key) != KEY_BYTES:
        raise SigningKeyError(f"{source}: a key has {KEY_BYTES} bytes, got {len(key)}")
    if not any(key):
        raise SigningKeyError(f"{source}: the all-zero key means 'no key' to MAVLink; make a random one "
                              f"(python -c \"import secrets; print(secrets.token_hex(32))\")")
    steps = {(b - a) % 256 for a, b in itertools.pairwise(key)}
    if len(set(key)) < MIN_DISTINCT or len(steps) < MIN_DISTINCT:
        raise SigningKeyError(f"{source}: too little entropy to be a random key ({len(set(key))} distinct byte values "
                              f"of {KEY_BYTES}, a pattern); make one with python -c \"import secrets; "
                              f"print(secrets.token_hex(32))\"")
    return key


def key_from_passphrase(passphrase: str, source: str = "--key-passphrase") -> bytes:
    """The 32-byte key of ``passphrase``: SHA-256 of its ASCII bytes (ArduPilot's convention, module docstring);
    :class:`SigningKeyError` naming ``source`` when the passphrase is too short, repetitive or not printable
    ASCII."""
    if not all(" " <= c <= "~" for c in passphrase):
        raise SigningKeyError(f"{source}: a passphrase is printable ASCII (what ArduPilot's tools hash); it has "
                              f"another character")
    if len(passphrase) < MIN_PASSPHRASE or len(set(passphrase)) < MIN_PASSPHRASE_DISTINCT:
        raise SigningKeyError(f"{source}: too weak ({len(passphrase)} characters, {len(set(passphrase))} distinct): a "
                              f"passphrase has at least {MIN_PASSPHRASE} characters with at least "
                              f"{MIN_PASSPHRASE_DISTINCT} distinct, e.g. five random words")
    return hashlib.sha256(passphrase.encode("ascii")).digest()


def load_signing_key(path: str | os.PathLike[str] | None = None, *, env: Mapping[str, str] = os.environ) -> bytes:
    """The 32-byte signing key: from the key file ``path`` if given, else from ``env[SHAKETABLE_MAVLINK_KEY]``.

    A key file holds exactly 32 raw bytes, or 64 hexadecimal digits, and only its owner may access it; the variable
    holds 64 hexadecimal digits. Raises :class:`SigningKeyError` (module docstring) when there is no key, or the file
    is open to others, or the key has the wrong length or format, or too little entropy.
    """
    if path is not None:
        source = f"signing key file {os.fspath(path)}"
        try:
            data = read_private_file(Path(path), source, "the rig's key", _MAX_KEY_FILE)
        except PrivateFileError as exc:
            raise SigningKeyError(str(exc)) from exc.__cause__
        if len(data) == KEY_BYTES and all(32 <= b < 127 for b in data):
            raise SigningKeyError(f"{source}: 32 printable characters: a password or half a hexadecimal key, not "
                                  f"{KEY_BYTES} random raw bytes nor {2 * KEY_BYTES} hexadecimal digits")
        if len(data) == KEY_BYTES:
            key = data
        else:
            try:
                text = data.decode("ascii")
            except UnicodeDecodeError:
                raise SigningKeyError(f"{source}: {len(data)} bytes, neither {KEY_BYTES} raw bytes nor "
                                      f"{2 * KEY_BYTES} hexadecimal digits") from None
            key = _parse_hex(text, source)
    elif env.get(KEY_ENV):
        source = f"environment variable {KEY_ENV}"
        key = _parse_hex(env[KEY_ENV], source)
    else:
        raise SigningKeyError(f"no MAVLink signing key: set {KEY_ENV} (64 hexadecimal digits) or give a key file")
    return check_key_strength(key, source)


def write_signing_key(path: str | os.PathLike[str]) -> bytes:
    """Make a new random key and write it to ``path`` as 64 hexadecimal digits and a newline, readable by its owner
    only (mode 0600 from creation, whatever the umask); FileExistsError if ``path`` exists. Returns the key."""
    key = os.urandom(KEY_BYTES)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as file:
        file.write(key.hex() + "\n")
    return key
