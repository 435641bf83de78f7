"""``rig serve``: the orchestrator as a service whose control plane is zenoh.

:class:`OrchestratorService` opens a zenoh session that listens on a loopback endpoint (scouting off,
:func:`protocols.zenoh.session_config`) and declares the queryables of :mod:`rig.service.keys`: ``start``,
``pause``, ``resume``, ``abort``, ``estop``, ``state``, ``queue`` and ``answer``. Each query is handled in a thread
of its own (zenoh's threads are never blocked); requests and replies are those of :mod:`rig.service.wire`. One
session at a time, played by :class:`~rig.service.session.ServiceSession` in a worker thread; its progress is
published as telemetry (:mod:`rig.service.telemetry`); control requests are logged in the session's events with
the source the transport vouches for (:mod:`rig.service.audit`).

``start``, ``resume``, ``queue`` and ``answer`` are accepted only when signed with the rig's key (``key_file``, else
``$SHAKETABLE_MAVLINK_KEY``; :mod:`protocols.zenoh.auth`); ``pause``, ``abort``, ``estop`` and ``state`` from anyone
(stopping never waits for a key). ``require_auth=False`` (``rig serve --no-auth``) checks no signatures.

A request whose args carry ``refused`` (a reason: the console passing on a viewer's control) is answered refused
and only logged, never acted on.

Each command's arguments and reply, the reply's fields, the refusals and why the commands are split so:
docs/service.md.
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zenoh

from protocols.signing_key import KEY_ENV, SigningKeyError, load_signing_key
from protocols.zenoh import EndpointError, LinkSecurity, session_config
from protocols.zenoh.auth import Verdict, Verifier
from protocols.zenoh.config import PLAIN
from protocols.zenoh.payloads import PayloadError
from rig.orchestrator import Progress
from rig.service.audit import escaped, request_source
from rig.service.keys import COMMANDS, DEFAULT_RIG, SIGNED_COMMANDS, ServiceKeys
from rig.service.operator import AnswerRefusedError
from rig.service.session import ServiceSession, StartRefusedError, StartRequest
from rig.service.telemetry import LivePublisher, TelemetryPublisher, display_limits
from rig.service.wire import REFUSALS, ServiceError, decode_request, encode_reply, verify

FINISH_WAIT = 30.0
"""How long ``start`` waits for a finished session to let go of its table or emulator [s]."""

LOGGED_CONTROLS = frozenset({"pause", "resume", "abort", "estop", "answer"})
"""Commands logged in the running session's events with their source."""

MAX_QUEUED = 32
"""Most sessions waiting in the service's queue."""

SHUTDOWN_WAIT = 150.0
"""How long :meth:`OrchestratorService.close` waits for an aborted session to come to rest [s]."""


class OrchestratorService:
    """The rig service (module docstring) listening on ``listen`` (e.g. ``tcp/127.0.0.1:7447``).

    ``sessions_dir`` holds the session files (created if missing; relative paths of requests are taken from it);
    ``key_file`` the rig's key (else ``$SHAKETABLE_MAVLINK_KEY``); ``rig`` the rig's name in the key space;
    ``say(message)`` reports what happens (e.g. to stderr); ``security`` the zenoh session's TLS identity (listen on
    ``tls/ADDRESS:PORT`` across hosts) or plain text off loopback allowed (``protocols.zenoh.config``), also used for
    the zenoh tables of its sessions unless ``table_security`` is given (``rig run --console``: a service on
    loopback, its table across hosts). Raises
    :class:`ServiceError` when it cannot listen or
    has no key while ``require_auth``. :meth:`close` aborts a running session and closes the zenoh session.
    """

    def __init__(self, listen: str, *, key_file: Path | None = None, sessions_dir: Path, rig: str = DEFAULT_RIG,
                 require_auth: bool = True, say: Callable[[str], None] = lambda message: None,
                 security: LinkSecurity = PLAIN, table_security: LinkSecurity | None = None) -> None:
        self.listen = listen
        self.security = security
        self.table_security = security if table_security is None else table_security
        self.keys = ServiceKeys.for_rig(rig)
        self.key_file = key_file
        self.sessions_dir = Path(sessions_dir).expanduser().resolve()
        self._say = say
        self._verifier = self._load_verifier(key_file, require_auth)
        self._verify_lock = threading.Lock()
        self._lock = threading.Lock()
        self._starting: ServiceSession | None = None
        self._current: ServiceSession | None = None
        self._queue: list[tuple[int, StartRequest]] = []
        self._queued = 0
        try:
            self.sessions_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ServiceError(f"sessions directory {self.sessions_dir}: {exc}") from None
        try:
            self._zenoh = zenoh.open(session_config(listen=[listen], security=security))
        except EndpointError as exc:
            raise ServiceError(str(exc)) from None
        except zenoh.ZError as exc:
            raise ServiceError(f"cannot listen on {listen}: {exc}") from None
        self._telemetry = TelemetryPublisher(self._zenoh, self.keys, self.snapshot)
        self._live = LivePublisher(self._zenoh, self.keys, self._live_tap)
        self._queryables = [self._zenoh.declare_queryable(self.keys.commands[command],
                                                          functools.partial(self._arrived, command))
                            for command in COMMANDS]
        self._token = self._zenoh.liveliness().declare_token(self.keys.alive)
        self._closed = False

    @property
    def authenticated(self) -> bool:
        """``start`` and ``resume`` must be signed."""
        return self._verifier is not None

    @staticmethod
    def _load_verifier(key_file: Path | None, require_auth: bool) -> Verifier | None:
        if not require_auth:
            return None
        try:
            return Verifier(load_signing_key(key_file))
        except SigningKeyError as exc:
            hint = "" if key_file is not None else f" (give --key-file or set ${KEY_ENV}; --no-auth to go without)"
            raise ServiceError(f"the service needs the rig's key to check start and resume: {exc}{hint}") from None

    # ----- state ----------------------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """The status fields of every reply and STATUS publication (:mod:`rig.service.wire`)."""
        with self._lock:
            session = self._starting or self._current
            queue = [{"id": n, "name": _name_of(r), "emulate": r.emulate, "attended": r.attended}
                     for n, r in self._queue]
        if session is None:
            return {"state": "idle", "message": "no session yet", "session": None, "active": False,
                    "progress": _plain(_progress_dict(None)), "queue": queue, "prompt": None}
        progress = _progress_dict(session)
        starting = session.orchestrator is None and session.alive
        prompt = session.operator.prompt if session.operator is not None and session.alive else None
        return {"state": "starting" if starting else progress["state"], "message": progress["message"],
                "session": None if session.path is None else str(session.path), "active": session.alive,
                "progress": _plain(progress), "queue": queue, "prompt": prompt}

    def _live_tap(self) -> tuple[str | None, Any, dict[str, float] | None] | None:
        """The current session's file, its orchestrator's live tap and its table's display limits, or None."""
        with self._lock:
            session = self._current
        if session is None or session.orchestrator is None:
            return None
        limits = display_limits(session.orchestrator.sequence.table.limits)
        return (None if session.path is None else str(session.path)), session.orchestrator.live, limits

    def _running(self) -> ServiceSession | None:
        """The session being played (not finished), else None."""
        with self._lock:
            current = self._current
        return current if current is not None and current.alive and not current.finished else None

    # ----- queries ----------------------------------------------------------------------------------------

    def _arrived(self, command: str, query: zenoh.Query) -> None:
        """zenoh's callback: hand the query to a thread of its own."""
        payload = query.payload.to_bytes() if query.payload is not None else b""
        attachment = query.attachment.to_bytes() if query.attachment is not None else None
        threading.Thread(target=self._handle, args=(command, query, payload, attachment),
                         name=f"service-{command}", daemon=True).start()

    def _handle(self, command: str, query: zenoh.Query, payload: bytes, attachment: bytes | None) -> None:
        try:
            try:
                asked, args = decode_request(payload)
            except PayloadError as exc:
                query.reply_err(f"{command}: {exc}".encode())
                return
            verdict = self._verdict(command, payload, attachment)
            extra: dict[str, Any]
            if asked != command:
                ok, message, extra = False, f"a {asked!r} request on the {command!r} key", {}
            elif "refused" in args:  # refused by the client that passes it on (a console: a viewer's): logged only
                ok, message, extra = False, f"refused by the console: {args['refused']}", {}
            elif command in SIGNED_COMMANDS and verdict not in (None, Verdict.SIGNED):
                ok, message, extra = False, f"{command} refused: {REFUSALS[verdict]}", {}
            else:
                handler = self._queue_session if command == "queue" else getattr(self, f"_{command}")
                ok, message, extra = handler(args)
            if (command in LOGGED_CONTROLS or "refused" in args) and asked == command:
                self._log_control(command, request_source(args.get("source"), verdict, attachment), ok, message)
            if not ok:
                self._say(f"{command}: {message}")
            status = {**self.snapshot(), "seq": self._telemetry.published, **extra}
            status.pop("message")
            query.reply(self.keys.commands[command], encode_reply(ok, status.pop("state"), message, **status))
        except zenoh.ZError:  # the querier went away
            pass
        except Exception as exc:  # a bug: answer it rather than leave the client waiting
            self._say(f"{command}: {type(exc).__name__}: {exc}")
            with contextlib.suppress(zenoh.ZError):
                query.reply_err(f"{command}: the service failed: {type(exc).__name__}: {exc}".encode())
        finally:
            query.drop()

    def _log_control(self, command: str, source: str, ok: bool, message: str) -> None:
        """A control request into the running session's events (``Orchestrator.log_event``) and to ``say``, with
        its source as the transport vouches for it (:func:`rig.service.audit.request_source`, escaped there); the
        message escaped too: one request, one line."""
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        text = f"{stamp} control {command} from {source}: {'accepted' if ok else 'refused: ' + escaped(message)}"
        self._say(text)
        with self._lock:
            session = self._starting or self._current
        orchestrator = None if session is None or not session.alive else session.orchestrator
        if orchestrator is not None:
            orchestrator.log_event(text)

    def _verdict(self, command: str, payload: bytes, attachment: bytes | None) -> Verdict | None:
        """The request's signature checked (None: the service checks none). A signed ``pause`` is checked too, so
        that its source can be trusted; ``state`` is never logged and not checked."""
        if self._verifier is None or command == "state":
            return None
        with self._verify_lock:
            return verify(self._verifier, self.keys.commands[command], payload, attachment)

    def _queue_session(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        try:
            request = StartRequest.from_args(args, self.sessions_dir)
        except StartRefusedError as exc:
            return False, str(exc).replace("start:", "queue:", 1), {}
        with self._lock:
            if len(self._queue) >= MAX_QUEUED:
                return False, f"the queue is full ({MAX_QUEUED} sessions): start or wait for one first", {}
            self._queued += 1
            self._queue.append((self._queued, request))
            number = self._queued
        self._telemetry.changed()
        return True, f"queued as session {number}: {_name_of(request)}", {"queued": number}

    def _start(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        if "queued" in args:
            return self._start_queued(args)
        try:
            request = StartRequest.from_args(args, self.sessions_dir)
        except StartRefusedError as exc:
            return False, str(exc), {}
        return self._start_request(request)

    def _start_queued(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        """``start`` of the queued session ``args["queued"]``: taken off the queue only when it starts."""
        number = args.get("queued")
        if set(args) != {"queued"} or isinstance(number, bool) or not isinstance(number, int):
            return False, "start: give {\"queued\": ID} alone to start a queued session", {}
        with self._lock:
            request = next((r for n, r in self._queue if n == number), None)
        if request is None:
            return False, f"start: no session {number} in the queue", {}
        ok, message, extra = self._start_request(request)
        if ok:
            with self._lock:
                self._queue = [(n, r) for n, r in self._queue if n != number]
            self._telemetry.changed()
        return ok, message, extra

    def _answer(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        with self._lock:
            session = self._current
        operator = None if session is None or not session.alive else session.operator
        if operator is None:
            return False, "answer: no attended session is running (nothing asks the operator)", {}
        try:
            return True, operator.answer(args.get("prompt"), args.get("reply"), args.get("fell")), {}
        except AnswerRefusedError as exc:
            return False, f"answer: {exc}", {}

    def _start_request(self, request: StartRequest) -> tuple[bool, str, dict[str, Any]]:
        deadline = time.monotonic() + FINISH_WAIT
        while True:
            with self._lock:
                busy = self._starting or self._current
                if busy is None or not busy.alive:
                    table = self.table_security
                    link = {} if table == PLAIN else {"tls": table.tls, "insecure_plain_tcp": table.insecure}
                    session = ServiceSession(request, sessions_dir=self.sessions_dir, key_file=self.key_file,
                                             on_update=self._telemetry.changed, say=self._say, link=link)
                    self._starting = session
                    break
                if busy is self._starting or not busy.finished or time.monotonic() > deadline:
                    where = busy.path or "a new session"
                    return False, (f"a session is running ({where}, {busy.progress.state.value}): only one at a "
                                   "time; pause, abort or wait for it"), {}
            busy.thread.join(0.1)  # finished: it lets go of its table or emulator
        self._telemetry.changed()
        session.start()
        session.wait_started()
        with self._lock:
            self._starting = None
            if session.error is None:
                self._current = session
        self._telemetry.changed()
        if session.error is not None:
            return False, session.error, {}
        return True, f"session started: {session.path}", {}

    def _pause(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        session = self._running()
        if session is None or session.orchestrator is None:
            return False, self._nothing("pause"), {}
        session.orchestrator.pause()
        return True, "pause requested: the session pauses at the end of the current record", {}

    def _resume(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        session = self._running()
        if session is None or session.orchestrator is None:
            return False, self._nothing("resume"), {}
        session.orchestrator.resume()
        return True, "resume requested", {}

    def _abort(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        return self._stop("abort", "abort requested: the table stops and returns home, the run is logged aborted")

    def _estop(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        return self._stop("emergency stop", "emergency stop requested: the table brakes, the run is logged aborted")

    def _stop(self, kind: str, message: str) -> tuple[bool, str, dict[str, Any]]:
        with self._lock:
            starting = self._starting
        session = starting or self._running()
        if session is None:
            return False, self._nothing(kind), {}
        session.stop(kind)
        return True, message, {}

    def _state(self, args: dict[str, Any]) -> tuple[bool, str, dict[str, Any]]:
        return True, self.snapshot()["message"], {}

    def _nothing(self, what: str) -> str:
        with self._lock:
            starting = self._starting is not None
        if starting:
            return f"cannot {what}: the session is still being prepared"
        return f"cannot {what}: no session is running on the rig service at {self.listen}"

    # ----- shutdown -------------------------------------------------------------------------------------

    def stop_session(self, kind: str = "abort") -> bool:
        """Abort (or ``"emergency stop"``) the session being prepared or played; False if there is none."""
        with self._lock:
            sessions = [s for s in (self._starting, self._current) if s is not None and s.alive and not s.finished]
        for session in sessions:
            session.stop(kind)
        return bool(sessions)

    def wait_idle(self, timeout: float = SHUTDOWN_WAIT) -> bool:
        """Wait until no session is prepared or played, at most ``timeout`` [s]; False if one still is."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                sessions = [s for s in (self._starting, self._current) if s is not None and s.alive]
            if not sessions:
                return True
            if time.monotonic() > deadline:
                return False
            sessions[0].thread.join(min(0.5, max(0.0, deadline - time.monotonic())))

    def close(self, timeout: float = SHUTDOWN_WAIT) -> None:
        """Abort a running session, wait for it to come to rest (at most ``timeout`` [s]) and close."""
        if self._closed:
            return
        if self.stop_session("abort"):
            self._say("shutting down: the running session is aborted")
        self.wait_idle(timeout)
        self._closed = True
        self._telemetry.close()
        with contextlib.suppress(zenoh.ZError):
            self._live.close()
        with contextlib.suppress(zenoh.ZError):
            self._token.undeclare()
            for queryable in self._queryables:
                queryable.undeclare()
        with contextlib.suppress(zenoh.ZError):
            self._zenoh.close()

    def __enter__(self) -> OrchestratorService:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _name_of(request: StartRequest) -> str:
    """A queued session's name: its sequence's (or resumed file's) name."""
    if request.resume is not None:
        return f"resume {request.resume.name}"
    return request.sequence.name if request.sequence is not None else f"{request.sequence_name}.toml"


def _progress_dict(session: ServiceSession | None) -> dict[str, Any]:
    """The session's progress as JSON types (read while the orchestrator's threads change it: retried)."""
    progress = Progress() if session is None else session.progress
    for _ in range(10):
        try:
            return progress.as_dict()
        except RuntimeError:  # "dictionary changed size during iteration": the outcomes grew meanwhile
            continue
    return Progress(state=progress.state, message=progress.message).as_dict()


def _plain(value: Any) -> Any:
    """``value`` with non-finite floats as None (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value
