"""Who may use the console: the tokens file (``--tokens FILE``), re-read when it changes, so that a token is added or
revoked without restarting the console, and a token may carry the date-time it expires at.

A tokens file is TOML, readable by its owner only (mode 0600, as the rig's key), one table per token::

    [[token]]
    name = "control-room"          # named in every control's source and in the console's log
    role = "operator"              # may watch and command
    token = "4Jx…"                 # at least MIN_TOKEN characters of [A-Za-z0-9_-]

    [[token]]
    name = "tablet"
    role = "viewer"                # may watch only: its controls are refused and logged
    token = "q9Z…"
    expires = 2026-12-31T18:00:00Z # optional: refused from then on (a date-time with its offset, Z or +01:00)

(a token: ``python -c "import secrets; print(secrets.token_urlsafe(32))"``). The operator token derived from the rig's
key (:mod:`rig.console.token`) stays an operator's, named ``rig key``. With a tokens file the console shows nothing
without a token: the feed, the state and the report need a browser session opened with a token of either role.

The file is looked at on every check (its size, modification time and inode); when it changed it is read again. A
file that no longer reads (bad TOML, a bad entry, mode opened to others, removed) grants nothing until it is fixed —
the console fails closed — and the reason is logged once. Browser sessions are checked against the file on every
request: revoking a token ends the sessions opened with it, and so does its expiry. A token past its ``expires`` is
refused with a message that says it expired and when (:meth:`TokensFile.expired`), and the refusal is logged once per
token and version of the file.
"""

from __future__ import annotations

import hashlib
import hmac
import re
import threading
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from protocols.private_file import PrivateFileError, read_private_file

ROLES = ("operator", "viewer")
"""The roles a token may have: an operator watches and commands, a viewer watches only."""

MIN_TOKEN = 32
"""Fewest characters of a token in the tokens file (32 of base64url's 64: 192 bits)."""

_TOKEN = re.compile(r"[A-Za-z0-9_-]+")
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9 _.@-]{0,62}")
_MAX_FILE = 1 << 20


class AccessError(ValueError):
    """The tokens file is unusable (one line: FILE[:LINE], which entry or field, what is wrong)."""


@dataclass(frozen=True)
class Grant:
    """What a token gives: the ``name`` of its holder and its ``role`` (one of :data:`ROLES`), until ``expires``
    (an aware date-time; None: no expiry)."""

    name: str
    role: str
    expires: datetime | None = None

    @property
    def may_command(self) -> bool:
        return self.role == "operator"

    def expired(self, now: datetime) -> bool:
        """Whether the token is past its expiry at ``now`` (an aware date-time)."""
        return self.expires is not None and now >= self.expires

    def expiry_text(self) -> str:
        """Its expiry in UTC, as the console says it (``2026-12-31T18:00:00Z``)."""
        assert self.expires is not None
        return self.expires.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


RIG_KEY_GRANT = Grant("rig key", "operator")
"""The grant of the operator token derived from the rig's key."""


def read_tokens(path: Path) -> dict[str, Grant]:
    """The tokens of the tokens file ``path`` (module docstring), keyed by the SHA-256 of the token (hex);
    :class:`AccessError` naming the file, the entry and the field when it is not one."""
    try:
        data = read_private_file(path, f"tokens file {path}", "the tokens", _MAX_FILE)
    except PrivateFileError as exc:
        raise AccessError(str(exc)) from None
    if len(data) > _MAX_FILE:
        raise AccessError(f"tokens file {path}: larger than {_MAX_FILE} bytes")
    try:
        document = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise AccessError(f"tokens file {path}: {exc}") from None
    unknown = sorted(set(document) - {"token"})
    if unknown:
        raise AccessError(f"tokens file {path}: unknown key {unknown[0]!r}; expected [[token]] tables")
    entries = document.get("token", [])
    if not isinstance(entries, list) or not all(isinstance(entry, dict) for entry in entries):
        raise AccessError(f"tokens file {path}: 'token' must be an array of tables ([[token]])")
    grants: dict[str, Grant] = {}
    names: set[str] = set()
    for number, entry in enumerate(entries, 1):
        where = f"tokens file {path}: [[token]] #{number}"
        extra = sorted(set(entry) - {"name", "role", "token", "expires"})
        if extra:
            raise AccessError(f"{where}: unknown field {extra[0]!r}; expected name, role, token, expires")
        name, role, token = entry.get("name"), entry.get("role"), entry.get("token")
        if not isinstance(name, str) or not _NAME.fullmatch(name) or name == RIG_KEY_GRANT.name:
            raise AccessError(f"{where}: name {name!r}: expected 1-63 letters, digits, ' ', '_', '.', '@' or '-' "
                              f"(not {RIG_KEY_GRANT.name!r})")
        if name in names:
            raise AccessError(f"{where}: name {name!r} given twice")
        if role not in ROLES:
            raise AccessError(f"{where} ({name}): role {role!r}: expected one of {', '.join(ROLES)}")
        if not isinstance(token, str) or len(token) < MIN_TOKEN or not _TOKEN.fullmatch(token):
            raise AccessError(f"{where} ({name}): token: expected at least {MIN_TOKEN} characters of "
                              f"[A-Za-z0-9_-] (python -c \"import secrets; print(secrets.token_urlsafe(32))\")")
        expires = entry.get("expires")
        if expires is not None and (not isinstance(expires, datetime) or expires.utcoffset() is None):
            raise AccessError(f"{where} ({name}): expires {expires!r}: expected a date-time with its offset, "
                              f"e.g. expires = 2026-12-31T18:00:00Z or 2026-12-31T19:00:00+01:00")
        digest = _digest(token)
        if digest in grants:
            raise AccessError(f"{where} ({name}): the same token as {grants[digest].name!r}")
        names.add(name)
        grants[digest] = Grant(name, role, expires)
    return grants


class TokensFile:
    """The tokens file ``path``, re-read when it changes (module docstring); thread-safe. The first read raises
    :class:`AccessError`; a later unreadable version grants nothing and is said once to ``say``."""

    def __init__(self, path: Path, say: Callable[[str], None] = lambda message: None,
                 clock: Callable[[], datetime] = lambda: datetime.now(UTC)) -> None:
        self.path = path
        self._say = say
        self._clock = clock
        self._lock = threading.Lock()
        self._grants = read_tokens(path)
        self._seen = self._signature()
        self._told: set[str] = set()  # the names whose expiry was logged since the file was last read

    def _signature(self) -> tuple[int, int, int] | None:
        try:
            info = self.path.stat()
        except OSError:
            return None
        return info.st_ino, info.st_size, info.st_mtime_ns

    def _current(self) -> dict[str, Grant]:
        with self._lock:
            seen = self._signature()
            if seen != self._seen:
                self._seen = seen
                self._told.clear()
                try:
                    self._grants = read_tokens(self.path)
                    self._say(f"tokens file {self.path} read again: {len(self._grants)} tokens")
                except AccessError as exc:
                    self._grants = {}
                    self._say(f"{exc}: no token of the file is accepted until it is fixed")
            return self._grants

    def _entry(self, token: str | None) -> Grant | None:
        if not token:
            return None
        digest = _digest(token.strip())
        grants = self._current()
        return next((grant for known, grant in grants.items() if hmac.compare_digest(known, digest)), None)

    def grant(self, token: str | None) -> Grant | None:
        """The grant of ``token`` in the file as it is now (None: not there, revoked or expired; an expired token's
        refusal is logged once per token and version of the file)."""
        grant = self._entry(token)
        if grant is None or not grant.expired(self._clock()):
            return grant
        with self._lock:
            first = grant.name not in self._told
            self._told.add(grant.name)
        if first:
            self._say(f"token of {grant.name!r} refused: it expired at {grant.expiry_text()}")
        return None

    def expired(self, token: str | None) -> Grant | None:
        """The entry of ``token`` when it is in the file but past its expiry (None otherwise): what a refusal
        names to say why."""
        grant = self._entry(token)
        return grant if grant is not None and grant.expired(self._clock()) else None


def _digest(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()
