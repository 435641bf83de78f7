"""The table controller over zenoh: ``open_table("zenoh://HOST:PORT/TABLE", key_file=..., tls=...)``.

This host opens a zenoh peer session connecting to the controller's ``tls/HOST:PORT`` (mutual TLS, ``tls``: a
:class:`~protocols.zenoh.tls.TlsFiles`) or ``tcp/HOST:PORT`` (loopback, or any address with
``insecure_plain_tcp``) and speaks the table link of :mod:`protocols.zenoh.table` on
``shaketable/TABLE/controller/...``. Everything is signed both ways (:mod:`protocols.zenoh.auth`: HMAC-SHA256 with
the rig's key, ``key_file`` else ``$SHAKETABLE_MAVLINK_KEY``); what the controller sends without a valid, fresh
signature is dropped and counted (:meth:`ZenohTable.link_stats`). zenoh's callback threads stamp each publication
with its arrival time; a **heartbeat thread** publishes HEARTBEAT at :data:`HEARTBEAT_RATE` [Hz] and a clock query
every :data:`CLOCK_EVERY` heartbeats. Commands are queries with a command id, retried with the same id at least
:data:`RETRY_SPACING` s apart; streams are SETPOINTS published reliably (``drivers.chunked``).

Each protocol decision and its reasons: docs/transports.md §zenoh: the host; the controller side is
``sim_table.zenoh_endpoint``.
"""

from __future__ import annotations

import contextlib
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from datetime import UTC, datetime
from typing import NoReturn, TypeVar

import numpy as np
import zenoh

from analysis.table.controller_limits import ControllerLevel, ControllerTrip
from analysis.table.model import TableModel
from drivers.bodies import TableBody
from drivers.chunked import ChunkedStreamController, CommandAnswer
from drivers.controller import (
    AccelBatch,
    CommandDeniedError,
    CommandFailedError,
    CommandRejectedError,
    Detection,
    SetpointRefusal,
    TableError,
    TableStatus,
    TableTimeoutError,
    TiltBatch,
    register_scheme,
    sleep_until,
)
from protocols.signing_key import load_signing_key
from protocols.zenoh import EndpointError, LinkSecurity, session_config, table_accel_selector, table_key
from protocols.zenoh.auth import Received, Signer, Verdict, Verifier, split_signed
from protocols.zenoh.payloads import PayloadError
from protocols.zenoh.table import (
    SETPOINTS_PER_CHUNK,
    Answer,
    CommandRequest,
    OwnerReport,
    SetpointChunk,
    decode_accel,
    decode_answer,
    decode_bodies,
    decode_clock_reply,
    decode_heartbeat,
    decode_limit_trip,
    decode_overturn,
    decode_owner,
    decode_refusal,
    decode_status,
    decode_tilt,
    encode_clock_request,
    encode_command,
    encode_heartbeat,
    encode_setpoints,
    fault_names,
    input_names,
    parse_table_url,
)
from protocols.zenoh.tls import TlsFiles, why_no_link

T = TypeVar("T")

CLOSE_WAIT = 1.0
"""Longest wait [s] for the zenoh session to close. Over a link that is gone (the cable pulled) zenoh waits 10 s
for its peer and then raises ``ZError('close operation timed out!')``; the session then closes in the background
and :meth:`ZenohTable.close` returns, so that a lost link ends the run within the link timeout, not 10 s later
with that error in place of the run's outcome."""

HEARTBEAT_RATE = 50.0
"""Host heartbeats per second. The controller stops the table after 100 ms without one: at 50 Hz that takes five
lost in a row (at 20 Hz one lost heartbeat left a 100 ms gap, and 5 % loss tripped it within seconds)."""

CLOCK_EVERY = 25
"""A clock query every this many heartbeats (2 Hz)."""

CLOCK_TIMEOUT = 0.5
"""How long a clock query waits for its answer [s] (a late answer is useless to the estimate anyway)."""

RETRY_SPACING = 0.01
"""Least time between two attempts of a command [s] (a query without a route ends at once)."""

_REFUSED = {Verdict.UNSIGNED: "refused_unsigned", Verdict.BAD_SIGNATURE: "refused_bad_signature",
            Verdict.STALE: "refused_stale", Verdict.FUTURE: "refused_future"}


class _QueryAnswer(CommandAnswer):
    """A command's ANSWER (the query's reply, ``answer``); the final answers of a motion arrive in ``finals`` while
    they stay in the table's ``finals_by_id`` under the command id."""

    def __init__(self, finals_by_id: dict[int, list[Answer]], cmd_id: int, answer: Answer,
                 finals: list[Answer]) -> None:
        self.finals_by_id, self.cmd_id, self.answer, self.finals = finals_by_id, cmd_id, answer, finals
        self.in_progress = answer.result == "in_progress"
        self.over_from_ns = answer.t_ns

    def shown(self, status: TableStatus) -> bool:
        """Taken at or after the answer: the controller reports a state change at once."""
        return status.t_ns >= self.answer.t_ns

    def reached(self) -> bool | None:
        return self.finals[0].result == "accepted" if self.finals else None

    def shows_end(self, status: TableStatus) -> bool:
        """Taken at or after the first final answer."""
        return status.t_ns >= self.finals[0].t_ns

    def close(self) -> None:
        self.finals_by_id.pop(self.cmd_id, None)


class ZenohTable(ChunkedStreamController):
    """A table controller at ``zenoh://HOST:PORT/TABLE`` (module docstring).

    Options: ``key_file`` (default ``$SHAKETABLE_MAVLINK_KEY``); ``tls`` this host's TLS identity (the link is then
    ``tls/``) and ``insecure_plain_tcp`` (a plain ``tcp/`` link off loopback: nothing encrypted); ``command_timeout``
    [s] per attempt and ``retries``; ``connect_timeout`` [s]; ``table`` the table model streamed trajectories are
    checked against (default: Table IV and the default hexapod); ``observe`` connect without claiming the table (a
    monitor: ``drivers.chunked``). A bad address for the link raises :class:`ValueError` here.
    """

    samples_per_chunk = SETPOINTS_PER_CHUNK

    def __init__(self, url: str, *, key_file: str | None = None, command_timeout: float = 0.15, retries: int = 4,
                 connect_timeout: float = 3.0, tls: TlsFiles | None = None, insecure_plain_tcp: bool = False,
                 table: TableModel | None = None, observe: bool = False) -> None:
        super().__init__(url, table, observe)
        self.address = parse_table_url(url)
        self.security = LinkSecurity(tls, insecure_plain_tcp)
        try:
            self.endpoint = self.address.endpoint_for(self.security)
            """The zenoh endpoint the host connects to (``tls/…`` or ``tcp/…``)."""
        except EndpointError as exc:
            raise ValueError(f"table URL {url!r}: {exc}") from None
        self.key_file = key_file
        self.command_timeout = command_timeout
        self.retries = retries
        self.connect_timeout = connect_timeout
        self._keys = {kind: table_key(self.address.table, kind) for kind in ("command", "clock", "setpoints",
                                                                            "host-heartbeat", "answer", "status",
                                                                            "overturn", "heartbeat", "tilt",
                                                                            "bodies", "refusal", "limit-trip")}
        self._session: zenoh.Session | None = None
        self._signer: Signer | None = None
        self._command_lock = threading.Lock()  # command ids, signing and sending a command
        self._setpoints_lock = threading.Lock()  # signing and sending a chunk
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._finals: dict[int, list[Answer]] = {}  # cmd id of a command sent, or moving -> its final answers
        self._clock_sent: deque[int] = deque(maxlen=64)
        self._next_cmd = secrets.randbits(63)
        self.command_attempts_unanswered = 0
        """Command queries that ended without an answer (and were sent again, or timed out)."""
        self.bad_payloads = 0
        """Publications of the controller that could not be decoded."""
        self.last_controller_heartbeat_ns: int | None = None
        """Host time [ns] of the controller's last HEARTBEAT."""
        self.refused = dict.fromkeys(_REFUSED.values(), 0)
        """Payloads of the controller dropped: without a signature (too short to hold one), with one that did not
        verify (another key or key expression, altered; an unsigned payload long enough to hold one), stale
        (replayed, reordered, too old) or stamped too far ahead (:mod:`protocols.replay`)."""
        self._owner_report: OwnerReport | None = None  # the last OWNER reply
        self._verifier: Verifier | None = None
        self._verify_lock = threading.Lock()  # zenoh calls back on several threads

    # ----- connection -----------------------------------------------------------------------------------

    def connect(self) -> None:
        if self._session is not None:
            return
        key = load_signing_key(self.key_file)
        self._verifier = Verifier(key)
        self._signer = Signer(key, secrets.randbits(64), self._verifier.guard.current)
        deadline = time.monotonic() + self.connect_timeout
        self.heap.hold()
        try:
            session = zenoh.open(session_config(connect=[self.endpoint], security=self.security))
        except zenoh.ZError as exc:
            self.heap.release()
            raise TableError(f"{self.url}: cannot open a zenoh session: {exc}") from None
        self._session = session
        self._closing.clear()
        try:
            keys = self._keys
            for key_expr, handler in ((keys["status"], self._on_status), (keys["answer"], self._on_answer),
                                      (keys["overturn"], self._on_overturn), (keys["heartbeat"], self._on_heartbeat),
                                      (keys["tilt"], self._on_tilt), (keys["refusal"], self._on_refusal),
                                      (keys["limit-trip"], self._on_limit_trip),
                                      (table_accel_selector(self.address.table), self._on_accel)):
                session.declare_subscriber(key_expr, self._receiver(handler))
            self._setpoints = session.declare_publisher(keys["setpoints"], express=True,
                                                        congestion_control=zenoh.CongestionControl.BLOCK)
            self._heartbeat = session.declare_publisher(keys["host-heartbeat"], express=True)
            self._command_querier = session.declare_querier(keys["command"], timeout=self.command_timeout)
            self._clock_querier = session.declare_querier(keys["clock"], timeout=CLOCK_TIMEOUT)
            self._thread = threading.Thread(target=self._heartbeat_loop, name="zenoh-heartbeat", daemon=True)
            self._thread.start()
            while not (self.clock.fitted and self.feedback.latest is not None and self._routes_ready()):
                if time.monotonic() > deadline:
                    self._no_answer()
                self._request_clock()  # round trips 20 ms apart until the clock's rate is fitted
                time.sleep(0.02)
            self._claim()
        except BaseException:
            self.close()
            raise

    def _no_answer(self) -> NoReturn:
        """As :meth:`ChunkedStreamController._no_answer`; over TLS, when nothing came at all, why the link was not
        made (:func:`~protocols.zenoh.tls.why_no_link`: which side refused which certificate)."""
        if self.security.tls is not None and self.feedback.latest is None and not any(self.refused.values()):
            raise TableTimeoutError(f"{self.url}: no answer from the table controller within {self.connect_timeout} s "
                                    f"over {self.endpoint}: {why_no_link(self.endpoint, self.security.tls)}")
        super()._no_answer()

    def bodies(self, timeout: float = 3.0) -> tuple[TableBody, ...] | None:
        """The bodies on the plate, from the controller's ``bodies`` queryable (a BODIES reply); None if it gives
        none within ``timeout`` [s] (a controller without the queryable)."""
        if self._session is None:
            raise TableError(f"{self.url}: not connected")
        for reply in self._session.get(self._keys["bodies"], timeout=timeout):
            bodies = self._decoded_reply(self._keys["bodies"], reply, decode_bodies)
            if bodies is not None:
                return tuple(TableBody(k, *body) for k, body in enumerate(bodies))
        return None

    def _decoded_reply(self, key: str, reply: zenoh.Reply, decode: Callable[[bytes], T]) -> T | None:
        """The payload of a reply to this host's query on ``key``, decoded; None for an error reply, one not signed
        by the controller (counted in :attr:`refused`) or one that does not decode (counted in ``bad_payloads``)."""
        if reply.ok is None:
            return None
        received = split_signed(reply.ok.payload.to_bytes())
        if not self._verified(key, received, reply=True):
            return None
        try:
            return decode(received.message)
        except PayloadError:
            self.bad_payloads += 1
            return None

    def _routes_ready(self) -> bool:
        return bool(self._setpoints.matching_status and self._heartbeat.matching_status
                    and self._command_querier.matching_status)

    def close(self) -> None:
        if self._session is None:
            return
        self._release()
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        session, self._session = self._session, None
        closer = threading.Thread(target=_close_quietly, args=(session,), name="zenoh-close", daemon=True)
        closer.start()
        closer.join(CLOSE_WAIT)
        self.feedback.close()
        self.heap.release()

    # ----- receiving (zenoh's callback threads) ----------------------------------------------------------

    def _receiver(self, handler: Callable[[bytes, int], None]) -> Callable[[zenoh.Sample], None]:
        """A subscriber callback: ``handler(message, arrival host ns)`` for a payload signed by the controller (the
        rest counted in :attr:`refused`); an undecodable payload is counted (zenoh would only log the exception)."""

        def receive(sample: zenoh.Sample) -> None:
            now = time.monotonic_ns()
            received = split_signed(sample.payload.to_bytes())
            if not self._verified(str(sample.key_expr), received):
                return
            try:
                handler(received.message, now)
            except PayloadError:
                self.bad_payloads += 1

        return receive

    def _verified(self, key: str, received: Received, *, reply: bool = False) -> bool:
        """Whether ``received`` came signed by the controller on ``key`` (``reply``: a reply to a query of this
        host, :meth:`~protocols.zenoh.auth.Verifier.verify_reply`); counted in :attr:`refused` if not."""
        assert self._verifier is not None  # connected
        with self._verify_lock:
            verdict = (self._verifier.verify_reply if reply else self._verifier.verify)(key, received)
            if verdict is not Verdict.SIGNED:
                self.refused[_REFUSED[verdict]] += 1
        return verdict is Verdict.SIGNED

    def _on_status(self, payload: bytes, now: int) -> None:
        report = decode_status(payload)
        self.feedback.publish_status(TableStatus(report.t_ns, report.state, report.buffer_depth,
                                                 report.last_chunk_seq, report.underruns, fault_names(report.faults),
                                                 report.refused_commands, report.pose, now, report.buffer_capacity,
                                                 report.samples_late, report.virtual_watchdog_ms * 1e-3,
                                                 input_names(report.inputs), report.following_error))

    def _on_answer(self, payload: bytes, now: int) -> None:
        answer = decode_answer(payload)
        finals = self._finals.get(answer.cmd_id)
        if finals is not None:
            finals.append(answer)
            self.feedback.notify()

    def _on_overturn(self, payload: bytes, now: int) -> None:
        event = decode_overturn(payload)
        self.feedback.publish_detection(Detection(event.event_id, event.body_id, event.direction, event.tilt,
                                                  event.t_ns))

    def _on_refusal(self, payload: bytes, now: int) -> None:
        refusal = decode_refusal(payload)
        self._publish_refusal(SetpointRefusal(refusal.t_ns, refusal.seq, refusal.reason))

    def _on_limit_trip(self, payload: bytes, now: int) -> None:
        report = decode_limit_trip(payload)
        try:
            level = ControllerLevel.decode((float(report.code), report.level))
        except ValueError as exc:
            raise PayloadError(f"LIMIT_TRIP: {exc}") from None
        self.feedback.publish_limit_trip(ControllerTrip(report.t_ns, report.sensor, report.value, level))

    def _on_heartbeat(self, payload: bytes, now: int) -> None:
        decode_heartbeat(payload)
        self.last_controller_heartbeat_ns = now

    def _on_accel(self, payload: bytes, now: int) -> None:
        batch = decode_accel(payload)
        self._publish_accel(AccelBatch(batch.sensor_id, batch.seq, batch.t_start_ns, batch.spacing_ns,
                                       batch.samples))

    def _on_tilt(self, payload: bytes, now: int) -> None:
        batch = decode_tilt(payload)
        self._publish_tilt(TiltBatch(batch.body_id, batch.seq, batch.t_start_ns, batch.spacing_ns, batch.angles))

    def _on_clock_reply(self, reply: zenoh.Reply) -> None:
        now = time.monotonic_ns()
        answer = self._decoded_reply(self._keys["clock"], reply, decode_clock_reply)
        if answer is None:
            return
        if answer.t_send_ns in self._clock_sent:
            self.clock.add(answer.t_send_ns, now, answer.t_controller_ns)
            self.feedback.notify()

    # ----- sending ----------------------------------------------------------------------------------------

    def _heartbeat_loop(self) -> None:
        period = round(1e9 / HEARTBEAT_RATE)
        deadline = time.monotonic_ns()
        beats = 0
        while not self._closing.is_set():
            self._heartbeat.put(self._signed(self._keys["host-heartbeat"], encode_heartbeat(time.monotonic_ns())))
            beats += 1
            if beats % CLOCK_EVERY == 0:
                self._request_clock()
            deadline = max(deadline + period, time.monotonic_ns())
            sleep_until(deadline)

    def _request_clock(self) -> None:
        now = time.monotonic_ns()
        self._clock_sent.append(now)
        self._clock_querier.get(self._on_clock_reply, payload=encode_clock_request(now))

    def _signed(self, key: str, message: bytes) -> bytes:
        assert self._signer is not None  # connected
        return self._signer.sign(key, message)

    # ----- commands (ChunkedStreamController) ---------------------------------------------------------

    motion_stopped_result = "cancelled"

    def _request(self, name: str, params: tuple[float, float]) -> _QueryAnswer:
        cmd_id = self._new_cmd_id()
        finals = self._finals[cmd_id] = []  # before the query: a quick final answer is not missed
        try:
            answer = self._query(name, params, cmd_id)
        except BaseException:
            del self._finals[cmd_id]
            raise
        return _QueryAnswer(self._finals, cmd_id, answer, finals)

    def _query(self, name: str, params: tuple[float, float], cmd_id: int) -> Answer:
        """Query ``name`` until answered (module docstring); the answer unless refused."""
        if self._session is None:
            raise TableError(f"{self.url}: not connected")
        message = encode_command(CommandRequest(cmd_id, name, params))
        key = self._keys["command"]
        errors: list[str] = []
        for attempt in range(self.retries + 1):
            started = time.monotonic()
            with self._command_lock:
                replies = self._command_querier.get(payload=self._signed(key, message))
            answer = self._first_answer(replies, cmd_id, errors)
            if answer is not None:
                break
            self.command_attempts_unanswered += 1
            if attempt < self.retries:
                time.sleep(max(0.0, started + RETRY_SPACING - time.monotonic()))
        else:
            last = f" (last error: {errors[-1]})" if errors else ""
            raise TableTimeoutError(f"{name}: no answer from {self.url} after {self.retries + 1} attempts of "
                                    f"{self.command_timeout} s{last}")
        self._check(name, answer)
        return answer

    def _first_answer(self, replies: zenoh.Handler[zenoh.Reply], cmd_id: int, errors: list[str]) -> Answer | None:
        """The answer among ``replies`` (iteration ends when the query does: answered, or its timeout)."""
        for reply in replies:
            result = reply.result
            if isinstance(result, zenoh.ReplyError):
                errors.append(result.payload.to_string())
                continue
            received = split_signed(result.payload.to_bytes())
            if not self._verified(self._keys["command"], received, reply=True):
                errors.append("an answer without a valid signature")
                continue
            try:
                answer = self._decode_reply(received.message)
            except PayloadError as exc:
                errors.append(str(exc))
                continue
            if answer.cmd_id == cmd_id:
                return answer
        return None

    def _decode_reply(self, message: bytes) -> Answer:
        """A command's reply: its ANSWER, or an OWNER (kept for :meth:`_owner_refusal`) as a ``rejected`` answer."""
        try:
            return decode_answer(message)
        except PayloadError:
            try:
                report = decode_owner(message)
            except PayloadError:
                pass
            else:
                self._owner_report = report
                return Answer(report.cmd_id, "rejected", 0)
            raise

    def _owner_refusal(self) -> str:
        """The owner as the controller's OWNER reply names it."""
        report = self._owner_report
        if report is None:
            return "another host since an unknown time"
        since = datetime.fromtimestamp(report.since_ms / 1000, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
        return (f"{report.owner} since {since}, last heard {report.silent_ms / 1000:.2f} s ago (its claim lapses "
                f"after {report.timeout_ms / 1000:g} s of silence, or when it disconnects)")

    def _new_cmd_id(self) -> int:
        with self._command_lock:
            self._next_cmd = (self._next_cmd + 1) % 2**64
            return self._next_cmd

    def _check(self, name: str, answer: Answer) -> None:
        """Raise the refusal ``answer`` to command ``name`` means, if any."""
        result = answer.result
        if result in ("accepted", "in_progress"):
            return
        state = self.feedback.latest.state if self.feedback.latest is not None else None
        upper = name.upper()
        if result == "denied":
            raise CommandDeniedError(upper, result, state, "missing or bad signature (are host and controller "
                                     "using the same signing key?)")
        if result == "rejected":
            owner = self._owner_report
            if owner is not None and owner.cmd_id == answer.cmd_id:  # refused with an OWNER reply
                raise CommandRejectedError(upper, result, state, f"table in use by {self._owner_refusal()}")
            raise CommandRejectedError(upper, result, state, "not accepted in this state")
        why = {"failed": "invalid parameters", "cancelled": "the motion was stopped before its target"}[result]
        raise CommandFailedError(upper, result, state, why)

    # ----- streaming (ChunkedStreamController) ---------------------------------------------------------

    def _encode_chunk(self, seq: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray,
                      end_of_stream: bool) -> bytes:
        return encode_setpoints(SetpointChunk(seq, t_start_ns, spacing_ns, samples, end_of_stream))

    def _send_chunk(self, message: bytes) -> None:
        with self._setpoints_lock:
            self._setpoints.put(self._signed(self._keys["setpoints"], message))

    # ----- diagnostics ----------------------------------------------------------------------------------

    def link_stats(self) -> dict[str, float | None]:
        """Clock estimate and round trips, accelerometer and body-tilt batches lost, duplicate overturn events
        dropped, command queries unanswered, undecodable publications, what was refused (:attr:`refused`), age of
        the controller's last heartbeat [s] (None before the first)."""
        beat = self.last_controller_heartbeat_ns
        return {**self.clock.stats(), **self.refused, "accel_batches_lost": self.accel_batches_lost,
                "tilt_batches_lost": self.tilt_batches_lost,
                "duplicate_detections": self.feedback.duplicate_detections,
                "command_attempts_unanswered": self.command_attempts_unanswered, "bad_payloads": self.bad_payloads,
                "controller_heartbeat_age_s": None if beat is None else (time.monotonic_ns() - beat) * 1e-9}


register_scheme("zenoh", ZenohTable)


def _close_quietly(session: zenoh.Session) -> None:
    """Close ``session``; a close that times out over a dead link (``ZError``) is the end of it anyway."""
    with contextlib.suppress(zenoh.ZError):
        session.close()
