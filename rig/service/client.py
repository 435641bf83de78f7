"""The client side of the rig service: :class:`ServiceClient` sends the service's commands over zenoh and follows its
telemetry (``rig run --service``, ``rig service …``, other programs).

    with ServiceClient("tcp/127.0.0.1:7447", key_file=Path("rig.key")) as client:
        with client.telemetry() as feed:
            session = client.start(sequence=Path("examples/quick.toml"), emulate=True)
            for status in feed:            # dicts: state, message, session, active, progress, t_ns, seq
                ...
        client.pause(); client.resume(); client.abort(); client.emergency_stop(); client.state()
        number = client.queue(Path("examples/quick.toml"), emulate=True, attended=True)   # started later:
        client.start_queued(number); client.answer(prompt_id, "done")                    # e.g. from the console

``pause``/``resume``/``abort``/``emergency_stop`` take an optional ``source`` (who asked: the service logs every
control request in the running session's events with it when the request is signed — ``rig.service.audit``).

Every command returns the service's reply (:mod:`rig.service.wire`) or raises :class:`~rig.service.wire.ServiceError`
with the service's reason; :class:`~rig.service.wire.ServiceUnavailableError` when no service answers.
With the rig's key (``key_file``, else ``$SHAKETABLE_MAVLINK_KEY``) every command but ``state`` is signed; ``start``,
``resume``, ``queue`` and ``answer`` must be (without a key a service that checks signatures refuses them).
"""

from __future__ import annotations

import contextlib
import os
import queue
import secrets
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import zenoh

from protocols.signing_key import KEY_ENV, SigningKeyError, load_signing_key
from protocols.zenoh import EndpointError, LinkSecurity, session_config
from protocols.zenoh.auth import Signer
from protocols.zenoh.config import PLAIN
from protocols.zenoh.payloads import Kind, PayloadError, decode_json
from protocols.zenoh.tls import why_no_link
from rig.service.keys import DEFAULT_RIG, ServiceKeys
from rig.service.session import StartRequest
from rig.service.telemetry import IDLE_PERIOD
from rig.service.wire import ServiceError, ServiceUnavailableError, decode_reply, encode_request, sign

CONNECT_TIMEOUT = 3.0
"""How long the client waits for the service's queryables to be reachable [s]."""

COMMAND_TIMEOUT = 5.0
"""How long a command waits for the service's reply [s] (``start``: :data:`START_TIMEOUT`)."""

START_TIMEOUT = 120.0
"""How long ``start`` waits [s]: the service reads and checks the sequence (every drive prepared) and opens the
table or starts the emulator before it answers."""

SILENCE = 5 * IDLE_PERIOD
"""A telemetry feed that hears nothing this long [s] takes the service for gone."""


class TelemetryFeed:
    """The service's STATUS publications as dicts (:mod:`rig.service.wire`), in arrival order; iterate, or
    :meth:`get` with a timeout. Iteration raises :class:`ServiceUnavailableError` after ``silence`` s without one
    (the service publishes at least every second)."""

    def __init__(self, session: zenoh.Session, key: str, endpoint: str, silence: float = SILENCE) -> None:
        self._queue: queue.Queue[dict[str, Any]] = queue.Queue()
        self._endpoint = endpoint
        self.silence = silence
        self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        with contextlib.suppress(PayloadError):  # not the service's status: ignored
            self._queue.put(decode_json(sample.payload.to_bytes(), Kind.STATUS))

    def get(self, timeout: float | None = None) -> dict[str, Any] | None:
        """The next status, or None when none arrives within ``timeout`` [s]."""
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def latest(self) -> dict[str, Any] | None:
        """The newest status received and not yet taken (the older ones are dropped), or None."""
        last = None
        with contextlib.suppress(queue.Empty):
            while True:
                last = self._queue.get_nowait()
        return last

    def __iter__(self) -> Iterator[dict[str, Any]]:
        while True:
            status = self.get(self.silence)
            if status is None:
                raise ServiceUnavailableError(f"the rig service at {self._endpoint} fell silent: no telemetry for "
                                              f"{self.silence:g} s")
            yield status

    def close(self) -> None:
        with contextlib.suppress(zenoh.ZError):
            self._subscriber.undeclare()

    def __enter__(self) -> TelemetryFeed:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ServiceClient:
    """A connection to the rig service listening at ``connect`` (``tcp/127.0.0.1:7447``) (module docstring).

    Raises :class:`ServiceUnavailableError` when nothing answers within ``connect_timeout`` [s] (over TLS, why the
    link was not made); ``timeout`` [s] bounds each command but ``start``; ``security`` this client's TLS identity
    (``connect`` a ``tls/`` endpoint) or plain text off loopback allowed.
    """

    def __init__(self, connect: str, key_file: Path | None = None, *, rig: str = DEFAULT_RIG,
                 connect_timeout: float = CONNECT_TIMEOUT, timeout: float = COMMAND_TIMEOUT,
                 security: LinkSecurity = PLAIN) -> None:
        self.endpoint = connect
        self.security = security
        self.keys = ServiceKeys.for_rig(rig)
        self.timeout = timeout
        self._signer = _signer(key_file)
        try:
            self._session = zenoh.open(session_config(connect=[connect], security=security))
        except EndpointError as exc:
            raise ServiceError(str(exc)) from None
        except zenoh.ZError as exc:
            raise ServiceUnavailableError(f"no rig service at {connect}: {exc}") from None
        try:
            self._wait_for_service(connect_timeout)
        except BaseException:
            self.close()
            raise

    def _wait_for_service(self, timeout: float) -> None:
        queriers = [self._session.declare_querier(key) for key in self.keys.commands.values()]
        deadline = time.monotonic() + timeout
        try:
            while not all(q.matching_status.matching  # type: ignore[attr-defined]  # stub: bool; run time: MatchingStatus
                          for q in queriers):
                if time.monotonic() > deadline:
                    why = (f": {why_no_link(self.endpoint, self.security.tls)}" if self.security.tls is not None
                           else f": is `rig serve --listen {self.endpoint}` running?")
                    raise ServiceUnavailableError(f"no rig service at {self.endpoint} (nothing answered within "
                                                  f"{timeout:g} s{why})")
                time.sleep(0.02)
        finally:
            for querier in queriers:
                querier.undeclare()

    # ----- commands -------------------------------------------------------------------------------------

    def start(self, sequence: Path | None = None, *, sequence_toml: str | None = None,
              sequence_name: str = "sequence", table: str | None = None, emulate: bool = False, speed: float = 1.0,
              output: Path | None = None, resume: Path | None = None, timeout: float = START_TIMEOUT) -> str:
        """Start a session (exactly one of ``sequence``, ``sequence_toml`` and ``resume``; see
        :class:`~rig.service.session.StartRequest`); the session file's path on the service's host. Paths are sent
        absolute (this process's working directory); the reply comes once the session runs."""

        request = StartRequest(_absolute(sequence), sequence_toml, sequence_name, table, emulate, speed,
                               _absolute(output), _absolute(resume))
        reply = self._command("start", request.to_args(), timeout=timeout, retries=0)
        return reply["session"]

    def queue(self, sequence: Path | None = None, *, table: str | None = None, emulate: bool = False,
              speed: float = 1.0, output: Path | None = None, resume: Path | None = None,
              attended: bool = False) -> int:
        """Queue a session (as :meth:`start`; ``attended``: its operator steps wait for :meth:`answer`) without
        starting it; its number in the service's queue (the status's ``queue``)."""
        request = StartRequest(_absolute(sequence), None, "sequence", table, emulate, speed, _absolute(output),
                               _absolute(resume), attended)
        return int(self._command("queue", request.to_args(), retries=0)["queued"])

    def start_queued(self, number: int, timeout: float = START_TIMEOUT) -> str:
        """Start the queued session ``number`` (signed); the session file's path."""
        return self._command("start", {"queued": number}, timeout=timeout, retries=0)["session"]

    def answer(self, prompt: int, reply: str = "done", fell: list[list[int]] | None = None,
               source: str | None = None) -> dict[str, Any]:
        """Answer the attended session's prompt ``prompt`` (``rig.service.operator``): ``"done"`` or
        ``"decline"``; ``fell`` ``[[body_id, ±1], …]`` for a "which bodies fell" prompt."""
        return self._command("answer", {"prompt": prompt, "reply": reply, "fell": fell or [], **_source(source)},
                             retries=0)

    def pause(self, source: str | None = None) -> dict[str, Any]:
        """Pause at the end of the current record (the table holds its tilt)."""
        return self._command("pause", _source(source))

    def resume(self, source: str | None = None) -> dict[str, Any]:
        """Continue after a pause (signed)."""
        return self._command("resume", _source(source))

    def abort(self, source: str | None = None) -> dict[str, Any]:
        """Stop now: the table decelerates and returns home, the current run is logged ``aborted``."""
        return self._command("abort", _source(source))

    def emergency_stop(self, source: str | None = None) -> dict[str, Any]:
        """Brake the table now; the current run is logged ``aborted``."""
        return self._command("estop", _source(source))

    def refused(self, command: str, source: str, reason: str) -> None:
        """Have the service log that ``command``, asked by ``source``, was refused here for ``reason`` (the console:
        a viewer's control): it goes into the running session's events like every control (signed, so that the
        service writes ``source``); the service does nothing else with it."""
        try:
            self._command(command, {"source": source, "refused": reason}, retries=0)
        except ServiceUnavailableError:
            raise
        except ServiceError:  # the answer expected: refused
            return
        raise ServiceError(f"the rig service at {self.endpoint} accepted a {command} refused here ({reason})")

    def state(self) -> dict[str, Any]:
        """The service's status: ``state``, ``message``, ``session``, ``active``, ``progress``."""
        return self._command("state")

    def telemetry(self, silence: float = SILENCE) -> TelemetryFeed:
        """Subscribe to the service's status publications (close the feed when done)."""
        return TelemetryFeed(self._session, self.keys.status, self.endpoint, silence)

    def _command(self, command: str, args: dict[str, Any] | None = None, *, timeout: float | None = None,
                 retries: int = 2) -> dict[str, Any]:
        """Send ``command`` until answered (at most ``retries`` more times); the reply when ``ok``."""
        key = self.keys.commands[command]
        payload = encode_request(command, args or {})
        timeout = self.timeout if timeout is None else timeout
        errors: list[str] = []
        for _ in range(retries + 1):
            attachment = sign(self._signer, key, payload) if self._signer and command != "state" else None
            try:
                replies = self._session.get(key, payload=payload, attachment=attachment, timeout=timeout)
            except zenoh.ZError as exc:
                raise ServiceUnavailableError(f"rig service at {self.endpoint}: {exc}") from None
            for reply in replies:
                result = reply.result
                if isinstance(result, zenoh.ReplyError):
                    errors.append(result.payload.to_string())
                    continue
                try:
                    body = decode_reply(result.payload.to_bytes())
                except PayloadError as exc:
                    errors.append(str(exc))
                    continue
                if not body["ok"]:
                    raise ServiceError(body["message"], body)
                return body
            if errors:
                raise ServiceError(f"{command}: the rig service at {self.endpoint} answered: {errors[-1]}")
        raise ServiceUnavailableError(f"no answer from the rig service at {self.endpoint} to {command} within "
                                      f"{timeout:g} s")

    def close(self) -> None:
        with contextlib.suppress(zenoh.ZError):
            self._session.close()

    def __enter__(self) -> ServiceClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _absolute(path: Path | None) -> Path | None:
    return None if path is None else Path(path).expanduser().absolute()


def _source(source: str | None) -> dict[str, Any]:
    """A control request's args: its ``source`` (who asked, logged in the session's events) when given."""
    return {} if source is None else {"source": source}


def _signer(key_file: Path | None) -> Signer | None:
    """A signer with the rig's key from ``key_file`` (else ``$SHAKETABLE_MAVLINK_KEY``); None without either."""
    if key_file is None and not os.environ.get(KEY_ENV):
        return None
    try:
        return Signer(load_signing_key(key_file), secrets.randbits(64))
    except SigningKeyError as exc:
        raise ServiceError(str(exc)) from None
