"""Setting a session up, as ``rig run``, ``rig demo`` and the rig service all do: the sequence read and checked,
the session file created (or an existing one resumed), the table opened (or an emulator started for it).

Errors are domain errors (:class:`~rig.sequence.SequenceError`, :class:`~rig.session.SessionError`,
:class:`~rig.emulator.EmulatorError`, :class:`NoTableError`); each front end words them for its own user (the CLI
names its options, the service its request's fields).
"""

from __future__ import annotations

import contextlib
import json
import secrets
import tempfile
from collections.abc import Callable, Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

import tomli_w

from analysis.table.model import TableModel
from rig import __version__
from rig.emulator import EmulatorProcess, specimen_flags, speed_flags
from rig.sequence import Sequence, load_sequence
from rig.session import SessionLog, read_session

EMULATOR_LISTEN = "mavlink://127.0.0.1:0"
"""Where an emulated table is started (MAVLink on loopback, any free port)."""

Counters = Callable[[], dict[str, Any]]
"""The emulator's own counters (its overturns, underruns, stops, refused commands), complete once it stopped."""


class NoTableError(ValueError):
    """No table to play on: neither a table URL (given, or ``table_url`` in the sequence) nor the emulator."""


def load_checked(path: Path) -> Sequence:
    """The sequence file read and checked against its table (SequenceError names file, line and field)."""
    sequence = load_sequence(path)
    sequence.check()
    return sequence


def resumed(path: Path) -> tuple[Sequence, SessionLog]:
    """The sequence stored in session file ``path``, checked, and the file opened to continue writing it."""
    sequence = Sequence.from_dict(read_session(path, data=False)["sequence"], source=str(path))
    sequence.check()
    return sequence, SessionLog.resume(path)


def create_log(sequence: Sequence, path: Path) -> SessionLog:
    """A new session file at ``path`` for ``sequence`` (refused by SessionError if the file exists)."""
    return SessionLog.create(path, rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                             software_version=__version__)


def default_session_path(sequence: Sequence, directory: Path | None = None) -> Path:
    """``session-YYYYMMDD-HHMMSS-NAME.h5`` in ``directory`` (default: the current one; local time)."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in sequence.name)
    return (directory or Path.cwd()) / f"session-{stamp}-{safe}.h5"


@contextlib.contextmanager
def table_for(sequence: Sequence, table: str | None, emulate: bool, key_file: Path | None,
              speed: float) -> Iterator[tuple[str, dict[str, Any], Counters | None]]:
    """The table URL, the driver options and (emulated) the emulator's counters.

    ``table`` (else the sequence's ``table_url``) is used as it is; with ``emulate`` an emulator process is started
    (and stopped on exit) with the sequence's bodies on its plate and its rig configuration (limits, hexapod,
    ``[dynamics]``; written out as TOML when it is not the default), ``speed`` its controller time per real time
    (math.inf: virtual time), and a one-session signing key unless ``key_file`` is given. NoTableError when there
    is neither.
    """
    if not emulate:
        url = table or sequence.table_url
        if url is None:
            raise NoTableError("no table: the sequence has no table_url, none was given, and the emulated table was "
                               "not asked for")
        yield url, ({"key_file": str(key_file)} if key_file else {}), None
        return
    with tempfile.TemporaryDirectory(prefix="rig-run-") as scratch:
        if key_file is None:
            key_file = Path(scratch) / "session.key"
            key_file.write_text(secrets.token_hex(32) + "\n")
        flags = [*specimen_flags(sequence.bodies), *speed_flags(speed)]
        if sequence.table != TableModel():  # the emulated table is the sequence's rig, not the default one
            rig = Path(scratch) / "rig.toml"
            rig.write_text(tomli_w.dumps(sequence.table.to_dict()))
            flags += ["--rig-config", str(rig)]
        emulator = EmulatorProcess.start(EMULATOR_LISTEN, *flags, key_file=key_file)
        counters: dict[str, Any] = {}
        try:
            yield emulator.url, {"key_file": str(key_file)}, lambda: counters
        finally:
            counters.update(emulator.stop())


def write_emulator_counters(session: Path, counters: dict[str, Any]) -> Path:
    """The emulator's counters beside the session file, as ``SESSION.emulator.json``: what the emulated table
    itself saw, to compare with the session's log."""
    path = session.with_name(session.name.removesuffix(".h5") + ".emulator.json")
    path.write_text(json.dumps(counters, indent=1) + "\n")
    return path
