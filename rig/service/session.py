"""One session of the rig service: the ``start`` request's arguments, and the worker thread that prepares the
session (sequence read and checked, table or emulator, session file) and plays it with the orchestrator.

The worker does what ``rig run --yes`` does (the steps of ``rig.orchestrator.setup``: the sequence read and
checked, the table or emulator, the session file created or resumed), unattended: the service has no operator at a
terminal, so bodies are taken as placed and runs start at once (a client confirms before it sends ``start``) —
unless the request is ``attended``: then the operator's steps wait for the service's ``answer`` command
(:mod:`rig.service.operator`, the console's prompt box).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.emulator import EmulatorError, counters_summary
from rig.orchestrator import Orchestrator, OrchestratorState, Progress
from rig.orchestrator.bodies import BodiesMismatchError
from rig.orchestrator.setup import (
    NoTableError,
    TableUnreachableError,
    choose_table,
    create_log,
    default_session_path,
    load_checked,
    table_for,
)
from rig.sequence import Sequence, SequenceError
from rig.service.operator import RemoteOperator
from rig.session import SessionError, SessionLog

_SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class StartRefusedError(Exception):
    """The session could not start (bad request, bad sequence, session file, table or emulator); nothing moved."""


@dataclass(frozen=True)
class StartRequest:
    """What ``start`` asks for (the request's ``args``).

    ``sequence``: a sequence file on the service's host, or ``sequence_toml``: its text (read as the file
    ``<sequence_name>.toml``; record paths in it are then relative to nowhere: use named records or absolute paths);
    ``table``: the table's URL (default: the sequence's ``table_url``), or ``emulate``: start the emulated table
    (``speed``: its controller time per real time, math.inf for virtual time: ``"max"`` in the request's
    ``args``); ``output``: the new session file (default
    ``session-DATE-TIME-NAME.h5`` in the service's sessions directory); ``resume``: continue that session file
    instead (no sequence then), on the table stored in it unless ``table`` or ``emulate`` is given; ``attended``:
    the operator's steps (place the bodies, and per the sequence confirm each run and say which bodies fell) wait for
    the service's ``answer`` command (:mod:`rig.service.operator`), else the session runs unattended. Relative paths
    are taken from the sessions directory.
    """

    sequence: Path | None = None
    sequence_toml: str | None = None
    sequence_name: str = "sequence"
    table: str | None = None
    emulate: bool = False
    speed: float = 1.0
    output: Path | None = None
    resume: Path | None = None
    attended: bool = False

    def to_args(self) -> dict[str, Any]:
        """The request's ``args`` (paths as given: make them absolute on the client)."""
        return {"sequence": None if self.sequence is None else str(self.sequence),
                "sequence_toml": self.sequence_toml, "sequence_name": self.sequence_name, "table": self.table,
                "emulate": self.emulate, "speed": "max" if math.isinf(self.speed) else self.speed,
                "output": None if self.output is None else str(self.output),
                "resume": None if self.resume is None else str(self.resume), "attended": self.attended}

    @classmethod
    def from_args(cls, args: dict[str, Any], base: Path) -> StartRequest:
        """The request from its ``args``; relative paths from ``base``. :class:`StartRefusedError` when malformed."""
        known = set(cls().to_args())
        unknown = sorted(set(args) - known)
        if unknown:
            raise StartRefusedError(f"start: unknown argument(s) {', '.join(unknown)}; expected {', '.join(known)}")

        def path(name: str) -> Path | None:
            value = args.get(name)
            if value is None:
                return None
            if not isinstance(value, str) or not value:
                raise StartRefusedError(f"start: {name} must be a path, got {value!r}")
            return base / Path(value).expanduser()

        def text(name: str, default: str | None) -> str | None:
            value = args.get(name, default)
            if value is not None and not isinstance(value, str):
                raise StartRefusedError(f"start: {name} must be a string, got {type(value).__name__}")
            return value

        emulate, speed, attended = args.get("emulate", False), args.get("speed", 1.0), args.get("attended", False)
        for name, flag in (("emulate", emulate), ("attended", attended)):
            if not isinstance(flag, bool):
                raise StartRefusedError(f"start: {name} must be true or false, got {flag!r}")
        if speed == "max":
            speed = math.inf
        elif isinstance(speed, bool) or not isinstance(speed, int | float) or not (math.isfinite(speed) and speed > 0):
            raise StartRefusedError(f"start: speed must be a number > 0 or \"max\", got {speed!r}")
        name = text("sequence_name", "sequence") or "sequence"
        if not _SAFE_NAME.fullmatch(name):
            raise StartRefusedError(f"start: sequence_name {name!r} must be 1..64 letters, digits, '.', '-', '_'")
        request = cls(path("sequence"), text("sequence_toml", None), name, text("table", None), emulate,
                      float(speed), path("output"), path("resume"), attended)
        given = sum(x is not None for x in (request.sequence, request.sequence_toml, request.resume))
        if given != 1:
            raise StartRefusedError("start: give exactly one of sequence (a file), sequence_toml (its text) or "
                                    "resume (a session file to continue)")
        if request.resume is not None and request.output is not None:
            raise StartRefusedError("start: output is not used with resume (the resumed file is written)")
        return request


class ServiceSession:
    """One session, prepared and played in its own worker thread (:meth:`start`).

    ``on_update()`` is called (from the worker's and the orchestrator's threads) whenever :attr:`progress` changes;
    ``say(message)`` reports to the service's log. After :meth:`wait_started`, :attr:`error` tells why it did not
    start (None: it runs, its file at :attr:`path`). An attended request's steps wait for :attr:`operator`.
    """

    def __init__(self, request: StartRequest, *, sessions_dir: Path, key_file: Path | None,
                 on_update: Callable[[], None], say: Callable[[str], None] = lambda message: None,
                 link: dict[str, Any] | None = None) -> None:
        self.request = request
        self.sessions_dir = sessions_dir
        self.key_file = key_file
        self.link = link or {}
        """More options of a zenoh table's driver: the service's TLS identity (``rig.orchestrator.setup.table_for``)."""
        self.path: Path | None = None
        self.progress = Progress(message="preparing the session: checking the sequence")
        self.orchestrator: Orchestrator | None = None
        self.final: OrchestratorState | None = None
        self.error: str | None = None
        self._on_update = on_update
        self._say = say
        self._started = threading.Event()
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._pending_stop: str | None = None  # "abort" | "emergency stop" asked before the orchestrator existed
        self.operator = RemoteOperator(on_change=on_update) if request.attended else None
        self.thread = threading.Thread(target=self._work, name="service-session", daemon=True)

    # ----- from the service's threads -------------------------------------------------------------------

    def start(self) -> None:
        """Prepare and play the session in the worker thread."""
        self.thread.start()

    def wait_started(self, timeout: float | None = None) -> bool:
        """Wait until the session runs (:attr:`error` None) or failed to start; False on timeout [s]."""
        return self._started.wait(timeout)

    @property
    def alive(self) -> bool:
        """The worker has not finished (preparing, playing, or letting go of the table or emulator)."""
        return not self._done.is_set()

    @property
    def finished(self) -> bool:
        """The orchestrator reached its final state (or the session failed to start)."""
        return self.final is not None or self.error is not None

    def stop(self, kind: str) -> None:
        """``"abort"`` or ``"emergency stop"`` now; before the orchestrator exists: as soon as it does."""
        with self._lock:
            orchestrator = self.orchestrator
            if orchestrator is None:
                self._pending_stop = kind
                return
        orchestrator.abort() if kind == "abort" else orchestrator.emergency_stop()
        if self.operator is not None:  # a prompt waiting: the orchestrator stops instead of waiting on
            self.operator.cancel()

    # ----- the worker -------------------------------------------------------------------------------------

    def _work(self) -> None:
        try:
            self._play()
        except Exception as exc:  # unexpected: report it, keep the service up
            what = f"{type(exc).__name__}: {exc}"
            if not self._started.is_set():
                self.error = f"the session could not start: {what}"
            else:
                self._say(f"session {self.path}: {what}")
                if self.final is None:
                    self.progress.state, self.final = OrchestratorState.FAULTED, OrchestratorState.FAULTED
                self.progress.message = what
        finally:
            self._started.set()
            self._done.set()
            self._on_update()

    def _play(self) -> None:
        with contextlib.ExitStack() as stack:
            try:
                sequence, log = self._prepare(stack)
            except StartRefusedError as exc:
                self.error = str(exc)
                self._started.set()
                return
            orchestrator = Orchestrator(sequence, self._url, log, table_options=self._options,
                                        operator=self.operator, on_update=lambda progress: self._on_update())
            with self._lock:
                self.orchestrator, self.progress = orchestrator, orchestrator.progress
                pending = self._pending_stop
            self._say(f"session {self.path}: started ({self._url})")
            self._started.set()
            if pending is not None:
                self.stop(pending)
            try:
                self.final = orchestrator.run()
            except Exception as exc:  # a bug or an unexpected failure: report it, keep the service up
                self.progress.state = OrchestratorState.FAULTED
                self.progress.message = f"the orchestrator failed: {type(exc).__name__}: {exc}"
                self.final = OrchestratorState.FAULTED
            self._say(f"session {self.path}: {self.final.value}: {self.progress.message}")
            self._on_update()
        if self._counters is not None:
            self._say(f"emulator: {counters_summary(self._counters())}")

    def _prepare(self, stack: contextlib.ExitStack) -> tuple[Sequence, Any]:
        """Sequence, table (or emulator) and session file, opened on ``stack``; :class:`StartRefusedError`."""
        request = self.request
        self._counters: Callable[[], dict[str, Any]] | None = None
        self._scratch: Path | None = None
        try:
            log, stored = None, None
            if request.resume is not None:
                log = SessionLog.resume(request.resume)
                stack.callback(log.close)
                sequence = Sequence.from_dict(log.sequence, source=str(request.resume))
                sequence.check()
                self.path, stored = request.resume, log.table
            else:
                sequence = self._load(stack)
                self.path = request.output or default_session_path(sequence, self.sessions_dir)
                if self.path.exists():
                    raise StartRefusedError(f"{self.path}: already exists; a session file is never overwritten, "
                                            "choose a new file name (or resume that session)")
            choice = choose_table(sequence, request.table, request.emulate,
                                  request.speed if request.emulate else None, stored)
            self._note("preparing the session: starting the emulated table" if choice.emulate
                       else "preparing the session")
            self._url, self._options, self._counters = stack.enter_context(
                table_for(sequence, choice.url, choice.emulate, self.key_file, choice.speed,
                          self.link if (choice.url or "").startswith("zenoh://") else None))
            if log is None:
                log = create_log(sequence, self.path, choice)
                stack.callback(log.close)
        except (SequenceError, SessionError, EmulatorError, TableUnreachableError, BodiesMismatchError, OSError) as exc:
            message = str(exc)
            if self._scratch is not None:  # the text's file is named as the client named it
                message = message.replace(f"{self._scratch}{os.sep}", "")
            raise StartRefusedError(message) from None
        except NoTableError:
            raise StartRefusedError("no table: give a table URL (rig run --table URL, or table_url in the sequence) "
                                    "or ask for the emulated table (rig run --emulate)") from None
        return sequence, log

    def _load(self, stack: contextlib.ExitStack) -> Sequence:
        request = self.request
        if request.sequence is not None:
            return load_checked(request.sequence)
        self._scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="rig-serve-")))
        path = self._scratch / f"{request.sequence_name.removesuffix('.toml')}.toml"
        path.write_text(request.sequence_toml or "", encoding="utf-8")
        return load_checked(path)

    def _note(self, message: str) -> None:
        self.progress.message = message
        self._on_update()
