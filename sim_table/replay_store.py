"""The controller's replay state on disk: what its signature guard has heard, kept across restarts.

A controller that forgot the stamps it had taken would take a capture replayed after a restart as long as its clock
let it (``protocols.replay``); one whose clock came back 60 s behind took a 20 s old signed ARM + SET_TILT (issue
42). So the emulator keeps its :class:`~protocols.replay.ReplayGuard`'s state in a file (``--replay-state FILE``;
by default beside its key file, ``KEYFILE.<transport>-replay.json``), restores it at start and refuses to start on a
file it cannot read or trust (:class:`ReplayStateError`, one line naming the file and the field).

The file is JSON::

    {"format": "shaketable-rig/replay-state/1", "transport": "mavlink" | "zenoh",
     "current": STAMP, "streams": [[STREAM, LAST_STAMP], ...]}   (least recently heard first)

MAVLink: a stream is ``[link id, system, component]`` (each 0–255), a stamp 0 ≤ s < 2^48 in 10 µs since
2015-01-01 UTC; zenoh: a stream is ``[sender, key expression]`` (sender 0 ≤ n < 2^64), a stamp 0 ≤ s < 2^64 in µs
since 1970-01-01 UTC. At most :data:`~protocols.replay.REMEMBERED_STREAMS` streams.

**When it is written**: before every signed motion command (ARM, HOME, SET_TILT, START_STREAM) takes effect
(:meth:`ReplayStore.save`, synchronous), every :data:`SAVE_PERIOD` while stamps are being taken (its own thread) and
at close. A crash thus loses at most the last :data:`SAVE_PERIOD` of heartbeat and setpoint-chunk stamps, never a
motion command's. **Crash-safe**: the state goes to a temporary file in the same directory, fsynced, renamed over
the file, and the directory is fsynced: a crash at any moment leaves the previous state or the new one, whole.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import threading
from collections.abc import Hashable
from pathlib import Path
from typing import Any

from protocols.replay import REMEMBERED_STREAMS, ReplayGuard, ReplayState

FORMAT = "shaketable-rig/replay-state/1"
"""The ``format`` field of a replay-state file."""

SAVE_PERIOD = 1.0
"""How often the state is written while stamps are being taken [s, real time]."""

_STAMP_LIMIT = {"mavlink": 2**48, "zenoh": 2**64}
"""Stamps of each transport are below this (MAVLink: 48 bits; zenoh: UNSIGNED64)."""

_MAX_FILE = 1 << 20  # 1024 streams of at most a few hundred bytes each


class ReplayStateError(ValueError):
    """A replay-state file that cannot be read or trusted: the message names the file and the field."""


def default_path(key_file: Path, transport: str) -> Path:
    """Where the replay state of ``transport`` lives by default: beside ``key_file``."""
    return key_file.with_name(f"{key_file.name}.{transport}-replay.json")


def _stamp(value: Any, transport: str, where: str) -> int:
    limit = _STAMP_LIMIT[transport]
    if not (isinstance(value, int) and not isinstance(value, bool) and 0 <= value < limit):
        raise ReplayStateError(f"{where}: expected an integer stamp in 0..{limit - 1}, got {value!r}")
    return value


def _stream(value: Any, transport: str, where: str) -> Hashable:
    if transport == "mavlink":
        if not (isinstance(value, list) and len(value) == 3
                and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value)):
            raise ReplayStateError(f"{where}: expected [link id, system, component], each 0..255, got {value!r}")
        return tuple(value)
    if not (isinstance(value, list) and len(value) == 2 and isinstance(value[0], int)
            and not isinstance(value[0], bool) and 0 <= value[0] < 2**64 and isinstance(value[1], str) and value[1]):
        raise ReplayStateError(f"{where}: expected [sender 0..2^64-1, key expression], got {value!r}")
    return tuple(value)


def parse_state(text: str, transport: str, source: str) -> ReplayState:
    """The state in a replay-state file's ``text`` for ``transport``; :class:`ReplayStateError` naming ``source``
    and the field otherwise."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ReplayStateError(f"{source}: line {exc.lineno}: not JSON ({exc.msg})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ReplayStateError(f"{source}: format: expected {FORMAT!r}")
    if data.get("transport") != transport:
        raise ReplayStateError(f"{source}: transport: the state of a {data.get('transport')!r} endpoint, this one is "
                               f"{transport!r} (give it a file of its own)")
    current = _stamp(data.get("current"), transport, f"{source}: current")
    streams = data.get("streams")
    if not isinstance(streams, list) or len(streams) > REMEMBERED_STREAMS:
        raise ReplayStateError(f"{source}: streams: expected a list of at most {REMEMBERED_STREAMS} [stream, stamp]")
    kept = []
    for k, entry in enumerate(streams):
        where = f"{source}: streams[{k}]"
        if not (isinstance(entry, list) and len(entry) == 2):
            raise ReplayStateError(f"{where}: expected [stream, stamp], got {entry!r}")
        kept.append((_stream(entry[0], transport, where), _stamp(entry[1], transport, where)))
    return ReplayState(current, tuple(kept))


def format_state(state: ReplayState, transport: str) -> str:
    """The text of a replay-state file holding ``state``."""
    return json.dumps({"format": FORMAT, "transport": transport, "current": state.current,
                       "streams": [[stream, last] for stream, last in state.streams]}) + "\n"  # tuples: JSON arrays


def write_atomically(path: Path, text: str) -> None:
    """Replace ``path`` by ``text``, crash-safe (module docstring)."""
    fd, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


class ReplayStore:
    """The replay state of one endpoint (``transport`` ``"mavlink"`` or ``"zenoh"``) in the file ``path``."""

    def __init__(self, path: Path, transport: str) -> None:
        if transport not in _STAMP_LIMIT:
            raise ValueError(f"transport must be one of {sorted(_STAMP_LIMIT)}, got {transport!r}")
        self.path, self.transport = Path(path), transport
        self._guard: ReplayGuard | None = None
        self._saved = 0  # the guard's changes at the last write
        self._lock = threading.Lock()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self.errors = 0
        """Writes that failed (the disk full, the directory gone): the motion command waiting on one is refused."""

    def load(self) -> ReplayState | None:
        """The state in the file; None when there is none yet (a first start). :class:`ReplayStateError` when it
        cannot be read or is damaged (the controller does not start on a state it cannot trust), or the file's
        directory cannot be written (the state could not be kept)."""
        source = f"replay state {self.path}"
        if not os.access(self.path.parent, os.W_OK):
            raise ReplayStateError(f"{source}: its directory cannot be written (give --replay-state FILE elsewhere)")
        try:
            with self.path.open("rb") as file:
                data = file.read(_MAX_FILE + 1)
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise ReplayStateError(f"{source}: {exc.strerror or exc}") from None
        if len(data) > _MAX_FILE:
            raise ReplayStateError(f"{source}: larger than {_MAX_FILE} bytes, not a replay state")
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            raise ReplayStateError(f"{source}: not UTF-8 text") from None
        return parse_state(text, self.transport, source)

    def keep(self, guard: ReplayGuard) -> None:
        """Write ``guard``'s state from now on: every :data:`SAVE_PERIOD` while it changes, on :meth:`save`, at
        :meth:`close`."""
        self._guard = guard
        self._saved = guard.changes
        self._thread = threading.Thread(target=self._periodic, name="replay-state", daemon=True)
        self._thread.start()

    def save(self) -> bool:
        """Write the guard's state now if it changed since the last write; whether the file holds it."""
        guard = self._guard
        if guard is None:
            return True
        with self._lock:
            changes = guard.changes
            if changes == self._saved:
                return True
            try:
                write_atomically(self.path, format_state(guard.state(), self.transport))
            except OSError:
                self.errors += 1
                return False
            self._saved = changes
            return True

    def _periodic(self) -> None:
        while not self._closing.wait(SAVE_PERIOD):
            self.save()

    def close(self) -> bool:
        """Stop the periodic writes and write the last state; whether the file holds it."""
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        return self.save()
