"""Setting a session up, as ``rig run``, ``rig demo`` and the rig service all do: the sequence read and checked,
the table chosen (given, the sequence's, or — resuming — the one the session file names) and asked whether it
answers (or an emulator started for it), then the session file created (or an existing one resumed). A session
file is created only once the table answered: a wrong URL leaves nothing behind.

Errors are domain errors (:class:`~rig.sequence.SequenceError`, :class:`~rig.session.SessionError`,
:class:`~rig.emulator.EmulatorError`, :class:`NoTableError`, :class:`TableUnreachableError`,
:class:`~rig.orchestrator.bodies.BodiesMismatchError`); each front end words them
for its own user (the CLI names its options, the service its request's fields).
"""

from __future__ import annotations

import contextlib
import json
import math
import tempfile
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import date, datetime
from pathlib import Path
from typing import Any

import tomli_w

from analysis.table.model import TableModel
from analysis.table.sensors import overdue
from protocols.signing_key import SigningKeyError, load_signing_key, write_signing_key
from rig import __version__
from rig.emulator import EmulatorProcess, specimen_flags, speed_flags
from rig.orchestrator.bodies import check_bodies
from rig.sequence import Sequence, SequenceError, load_sequence
from rig.session import WRITING, SessionError, SessionLog, is_disk_full, read_session, writer_state

EMULATOR_LISTEN = "mavlink://127.0.0.1:0"
"""Where an emulated table is started (MAVLink on loopback, any free port)."""

Counters = Callable[[], dict[str, Any]]
"""The emulator's own counters (its overturns, underruns, stops, refused commands), complete once it stopped."""


class NoTableError(ValueError):
    """No table to play on: neither a table URL (given, or ``table_url`` in the sequence) nor the emulator."""


class TableUnreachableError(RuntimeError):
    """The table at the URL did not answer, or answered and cannot be used (its URL or key, a drive the CANopen
    master refuses: the message says which); nothing was written."""


@dataclass(frozen=True)
class TableChoice:
    """Where a session plays: the table at ``url``, or (``emulate``) the emulated table at ``speed`` (controller time
    per real time, math.inf: virtual time) with the sequence's bodies, rig and ``[dynamics]``. Stored in the session
    file (root attribute ``table``) so that ``rig run --resume`` plays on the same table unless told otherwise."""

    url: str | None = None
    emulate: bool = False
    speed: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """As stored in the session file (speed ``"max"`` for virtual time: JSON has no infinity)."""
        if self.emulate:
            return {"emulate": True, "speed": "max" if math.isinf(self.speed) else self.speed}
        return {"url": self.url}

    @classmethod
    def from_dict(cls, stored: dict[str, Any]) -> TableChoice:
        """The choice stored by :meth:`to_dict`; ValueError names what is wrong."""
        if stored.get("emulate") is True:
            speed = stored.get("speed", 1.0)
            return cls(emulate=True, speed=math.inf if speed == "max" else float(speed))
        if isinstance(stored.get("url"), str) and stored["url"]:
            return cls(url=stored["url"])
        raise ValueError(f"table {stored!r}: expected {{'url': …}} or {{'emulate': true, 'speed': …}}")


def choose_table(sequence: Sequence, table: str | None, emulate: bool, speed: float | None,
                 stored: dict[str, Any] | None = None) -> TableChoice:
    """The table to play on: ``table`` if given, else the emulator if ``emulate``, else the session file's
    ``stored`` choice (resuming; its speed unless ``speed`` is given), else the sequence's ``table_url``.
    NoTableError when there is none."""
    if table is not None:
        return TableChoice(url=table)
    before = TableChoice.from_dict(stored) if stored else None
    if emulate:
        fallback = before.speed if before is not None and before.emulate else 1.0
        return TableChoice(emulate=True, speed=fallback if speed is None else speed)
    if before is not None:
        return TableChoice(emulate=True, speed=speed) if before.emulate and speed is not None else before
    if sequence.table_url is not None:
        return TableChoice(url=sequence.table_url)
    raise NoTableError("no table: the sequence has no table_url, none was given, and the emulated table was not "
                       "asked for")


def load_checked(path: Path) -> Sequence:
    """The sequence file read and checked against its table (SequenceError names file, line and field), and its
    rig's sensors' calibration dates (:func:`check_sensors`)."""
    sequence = load_sequence(path)
    sequence.check()
    check_sensors(sequence)
    return sequence


def check_sensors(sequence: Sequence, today: date | None = None) -> None:
    """A warning for each sensor (accelerometer, tilt sensor) of the sequence's rig whose calibration was due on or
    before ``today`` (default: the local date); SequenceError instead when the rig configuration refuses overdue sensors
    (``[sensors] overdue = "refuse"``, ``analysis.table.sensors``)."""
    sheets = sequence.table.sensors
    late = overdue(sheets, today or date.today())
    if late and sheets.overdue == "refuse":
        sheet = late[0]
        raise SequenceError(sheet.source, sheet.due_line, sheet.due_key,
                            f"{sheet.overdue_problem()}; the rig configuration refuses overdue sensors "
                            "(sensors.overdue = \"refuse\"): recalibrate it and give its new calibrated and due dates")
    for sheet in late:
        where = f"{sheet.source}:{sheet.due_line}" if sheet.due_line else sheet.source
        warnings.warn(f"{where}: {sheet.due_key}: {sheet.overdue_problem()}: recalibrate it (docs/sensors.md)",
                      stacklevel=2)


def resumed(path: Path) -> tuple[Sequence, dict[str, Any] | None]:
    """The sequence stored in session file ``path``, checked, and the table it played on as stored (None in files
    that do not say); open the file for writing with :func:`resume_log` once the table answered. SessionError at
    once when another process writes the file (before any table or emulator is started)."""
    if writer_state(path) == WRITING:
        raise SessionError(f"{path}: the session file is being written by another process (a rig run still going?); "
                           "expected no other writer")
    session = read_session(path, data=False)
    sequence = Sequence.from_dict(session["sequence"], source=str(path))
    sequence.check()
    check_sensors(sequence)
    stored = session["attrs"].get("table")
    return sequence, json.loads(stored) if isinstance(stored, str) and stored else None


def resume_log(path: Path) -> SessionLog:
    """Session file ``path`` opened to continue writing it (runs cut by a crash marked interrupted)."""
    return SessionLog.resume(path)


def create_log(sequence: Sequence, path: Path, table: TableChoice | None = None) -> SessionLog:
    """A new session file at ``path`` for ``sequence`` played on ``table`` (refused by SessionError if the file
    exists)."""
    return SessionLog.create(path, rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                             software_version=__version__, table=None if table is None else table.to_dict())


def default_session_path(sequence: Sequence, directory: Path | None = None) -> Path:
    """``session-YYYYMMDD-HHMMSS-NAME.h5`` in ``directory`` (default: the current one; local time)."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in sequence.name)
    return (directory or Path.cwd()) / f"session-{stamp}-{safe}.h5"


def probe_table(url: str, options: dict[str, Any], sequence: Sequence) -> None:
    """Connect to the table at ``url``, compare the bodies it reports with the sequence's, and let go:
    TableUnreachableError unless it answers (its clock and a status: `drivers.controller.TableController.connect`),
    BodiesMismatchError (`rig.orchestrator.bodies`) when its bodies are not the sequence's."""
    from drivers.controller import TableError, TableTimeoutError, open_table

    try:
        with open_table(url, **options) as table:
            reported = table.bodies()
    except SigningKeyError as exc:
        raise TableUnreachableError(f"the table at {url} was not contacted: {exc}") from None
    except (TableTimeoutError, OSError) as exc:
        raise TableUnreachableError(f"the table at {url} did not answer: {exc}") from None
    except (TableError, ValueError) as exc:  # it answered, and refused (a drive it cannot drive, a bad option)
        raise TableUnreachableError(f"the table at {url} cannot be used: {exc}") from None
    if reported is None:
        warnings.warn(f"the table at {url} does not report the bodies on its plate: they are not checked against "
                      "the sequence's (docs/table-controller.md, Bodies on the plate)", stacklevel=2)
    check_bodies(sequence.bodies, reported, url)


@contextlib.contextmanager
def table_for(sequence: Sequence, table: str | None, emulate: bool, key_file: Path | None,
              speed: float, link: dict[str, Any] | None = None,
              ) -> Iterator[tuple[str, dict[str, Any], Counters | None]]:
    """The table URL, the driver options and (emulated) the emulator's counters.

    ``table`` (else the sequence's ``table_url``) is used once it answered (:func:`probe_table`:
    TableUnreachableError otherwise); with ``emulate`` an emulator process is started
    (and stopped on exit) with the sequence's bodies on its plate and its rig configuration (limits, hexapod,
    ``[dynamics]``; written out as TOML when it is not the default), ``speed`` its controller time per real time
    (math.inf: virtual time), and a one-session signing key unless ``key_file`` is given. NoTableError when there
    is neither. ``link``: more options of the table's driver (a zenoh table's TLS identity: ``rig.cli.network``).
    """
    if key_file is not None:
        try:
            load_signing_key(key_file)  # the emulator would refuse it too, less readably
        except SigningKeyError as exc:
            raise TableUnreachableError(f"the table was not contacted: {exc}") from None
    if not emulate:
        url = table or sequence.table_url
        if url is None:
            raise NoTableError("no table: the sequence has no table_url, none was given, and the emulated table was "
                               "not asked for")
        options: dict[str, Any] = {**({"key_file": str(key_file)} if key_file else {}), **(link or {})}
        if url.startswith("canopen:"):  # this host is the drives' master: it needs the rig's [drives] and geometry
            options = {"table": sequence.table}
        probe_table(url, options, sequence)
        yield url, options, None
        return
    with tempfile.TemporaryDirectory(prefix="rig-run-") as scratch:
        if key_file is None:
            key_file = Path(scratch) / "session.key"
            write_signing_key(key_file)
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


class CountersNotWrittenError(SessionError):
    """The emulator's counters could not be written beside the session file (the session file is not affected);
    the message starts with ``disk full:`` when there was no room."""


def write_emulator_counters(session: Path, counters: dict[str, Any]) -> Path:
    """The emulator's counters beside the session file, as ``SESSION.emulator.json``: what the emulated table
    itself saw, to compare with the session's log. :class:`CountersNotWrittenError` when the file cannot be written
    (a full disk: often right after a session the disk ended); no part of it is left behind."""
    path = session.with_name(session.name.removesuffix(".h5") + ".emulator.json")
    try:
        path.write_text(json.dumps(counters, indent=1) + "\n")
    except OSError as exc:
        with contextlib.suppress(OSError):
            path.unlink(missing_ok=True)
        why = "disk full" if is_disk_full(exc) else "cannot write"
        raise CountersNotWrittenError(f"{why}: {path}: the emulator's counters were not written "
                                      f"({exc.strerror or exc}); the session file is not affected") from None
    return path
