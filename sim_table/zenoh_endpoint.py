"""The emulator's zenoh side: the controller end of the table link (``protocols.zenoh.table``).

``zenoh://HOST:PORT/TABLE`` opens a zenoh peer session listening on ``tls/HOST:PORT`` (mutual TLS) or
``tcp/HOST:PORT`` (loopback unless explicitly insecure; port 0: a free port, probed) and serves the keys
``shaketable/TABLE/controller/...``; while it serves it declares the liveliness token
``shaketable/TABLE/alive/table``. zenoh's callback threads stamp every host message with its arrival time and queue
it; the emulator's tick thread takes the queue in arrival order (:meth:`ZenohEndpoint.take`, each message an action
on the :class:`ControllerCore` at its arrival time), checks signatures and sends. Commands are queries answered
with an ANSWER; the last :data:`REMEMBERED_COMMANDS` are remembered by id, and a repeat is answered, not re-run.
Motion commands and chunks need a valid, fresh signature; everything the controller sends is signed. One host owns
the table at a time (``sim_table.ownership``); heartbeats every :data:`HEARTBEAT_PERIOD` s; ``loss`` and ``delay``
inject faults.

Each protocol decision, its counters and its reasons: docs/transports.md §zenoh: the controller; the host side is
``drivers.zenoh``.
"""

from __future__ import annotations

import contextlib
import heapq
import math
import secrets
import socket
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from analysis.table.controller_limits import ControllerTrip
from protocols.zenoh import EndpointError, LinkSecurity, alive_key, session_config, table_key
from protocols.zenoh.auth import Signer, Verdict, Verifier, replay_guard, sender_of, split_signed
from protocols.zenoh.config import PLAIN
from protocols.zenoh.payloads import PayloadError
from protocols.zenoh.table import (
    ACCEL_PER_BATCH,
    TILT_PER_BATCH,
    AccelSamples,
    Answer,
    ClockReply,
    LimitTripReport,
    Overturn,
    OwnerReport,
    Refusal,
    StatusReport,
    TableUrl,
    TiltSamples,
    decode_clock_request,
    decode_command,
    decode_heartbeat,
    decode_setpoints,
    encode_accel,
    encode_answer,
    encode_bodies,
    encode_clock_reply,
    encode_heartbeat,
    encode_limit_trip,
    encode_overturn,
    encode_owner,
    encode_refusal,
    encode_status,
    encode_tilt,
    parse_table_url,
)
from sim_table.controller import SIGNED_COMMANDS, Command, ControllerCore, Done, Refused, Result, Snapshot, State
from sim_table.endpoint import Action, Batch, BatchedTelemetry, Batcher, BodyOnPlate, EndpointOptions
from sim_table.ownership import OWNER_TIMEOUT, Owner, Ownership
from sim_table.replay_store import ReplayStore

REMEMBERED_COMMANDS = 256
"""Commands remembered by id for recognising retries."""

HEARTBEAT_PERIOD = 0.05
"""The controller's heartbeat period [s, real time] (20 Hz)."""

EVENT_RESENDS = 3
"""Overturn events are sent again this many times ..."""

EVENT_RESEND_PERIOD = 0.1
"""... this far apart [s, real time]."""

PORT_ATTEMPTS = 5
"""Free ports tried for port 0 (another process may take a probed port before zenoh binds it)."""

_VERDICT_COUNTERS = {Verdict.UNSIGNED: "unsigned", Verdict.BAD_SIGNATURE: "bad_signatures",
                     Verdict.STALE: "stale_signatures", Verdict.FUTURE: "future_signatures"}


@dataclass
class LinkCounters:
    """What the endpoint counted (reported at exit)."""

    messages_received: int = 0
    messages_dropped: int = 0  # injected loss, inbound
    messages_sent: int = 0
    messages_not_sent: int = 0  # injected loss, outbound
    bad_payloads: int = 0
    unsigned: int = 0  # commands and chunks without a signature
    bad_signatures: int = 0
    stale_signatures: int = 0  # replayed, reordered or too old
    future_signatures: int = 0  # stamped too far ahead of the current stamp
    replay_state_unsaved: int = 0  # motion commands refused: the replay state could not be written first
    heartbeats_refused: int = 0  # host heartbeats without a valid, fresh signature
    heartbeats_other_host: int = 0  # signed by another sender than the table's owner
    commands_other_host: int = 0  # signed motion commands refused: another sender owns the table
    chunks_other_host: int = 0  # signed setpoint chunks dropped: another sender owns the table
    clock_answered: int = 0
    duplicate_commands: int = 0
    chunks_stalled: int = 0
    accel_batches_sent: int = 0
    accel_samples_sent: int = 0
    tilt_batches_sent: int = 0
    tilt_samples_sent: int = 0
    overturn_events: int = 0
    overturn_messages_sent: int = 0
    refusals_sent: int = 0
    limit_trips_sent: int = 0
    status_sent: int = 0


class ZenohEndpoint(BatchedTelemetry):
    """The controller's zenoh endpoint for ``address`` (module docstring).

    ``key`` (32 bytes) verifies the host's signatures and signs what the controller sends; ``clock`` maps host
    monotonic ns to controller ns; ``loss`` (probability) and ``delay`` [s] inject faults with ``seed``; ``bodies``
    the specimens on the plate (the ``bodies`` queryable's reply); ``replay_state`` the file that keeps the signatures'
    stamps across restarts (``sim_table.replay_store``; None: in memory only).
    """

    def __init__(self, address: TableUrl, key: bytes, clock: Callable[[int], int], *, loss: float = 0.0,
                 delay: float = 0.0, seed: int = 0, virtual_time: bool = False,
                 bodies: tuple[BodyOnPlate, ...] = (), security: LinkSecurity = PLAIN,
                 replay_state: Path | None = None) -> None:
        if not (0.0 <= loss < 1.0 and delay >= 0.0 and math.isfinite(delay)):
            raise ValueError(f"loss must be in [0, 1) and delay >= 0 s, got {loss!r}, {delay!r}")
        self.clock = clock
        self.loss = loss
        self.delay_ns = round(delay * 1e9)
        self._batch_congestion = zenoh.CongestionControl.BLOCK if virtual_time else zenoh.CongestionControl.DROP
        self.counters = LinkCounters()
        self.stall_chunks = False
        """Set by the owner to drop every setpoint chunk from then on (injected stalled stream)."""
        self._store = ReplayStore(replay_state, "zenoh") if replay_state is not None else None
        self._verifier = Verifier(key, replay_guard(self._store.load() if self._store is not None else None))
        self._signer = Signer(key, secrets.randbits(64), self._verifier.guard.current)
        self._ownership = Ownership(round(OWNER_TIMEOUT * 1e9))  # owners are signing sender ids
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()  # the random numbers, the inbox, the counters of several threads
        self._session, self.address = _listen(address, security)
        if self._store is not None:
            self._store.keep(self._verifier.guard)
        self._keys = {kind: table_key(self.address.table, kind)
                      for kind in ("command", "clock", "setpoints", "host-heartbeat", "answer", "status", "overturn",
                                   "heartbeat", "tilt", "bodies", "refusal", "limit-trip")}
        self._bodies_payload = encode_bodies(list(bodies))
        declare = self._session.declare_publisher
        self._status = declare(self._keys["status"], express=True)
        self._answer = declare(self._keys["answer"], express=True)
        self._overturn = declare(self._keys["overturn"])
        self._refusal = declare(self._keys["refusal"])
        self._limit_trip = declare(self._keys["limit-trip"])
        self._heartbeat = declare(self._keys["heartbeat"], express=True)
        self._tilt_publisher = declare(self._keys["tilt"], congestion_control=self._batch_congestion)
        self._accel_publishers: dict[int, zenoh.Publisher] = {}
        self._entities: list[Any] = []
        self._inbox: deque[tuple[int, str, zenoh.Query | None, bytes]] = deque()  # (due, kind, query, payload)
        self._outbox: list[tuple[int, int, Callable[[], None], Callable[[], None] | None]] = []  # delayed:
        # (due, n, deliver, discard)
        self._queued = 0
        self._answers: OrderedDict[int, tuple[bytes, Result]] = OrderedDict()  # cmd id -> (message, result)
        self._requesters: dict[Command, int] = {}  # motion in progress -> its cmd id
        self._accel = Batcher(ACCEL_PER_BATCH)
        self._tilt = Batcher(TILT_PER_BATCH)
        self._resends: list[tuple[int, int, int, bytes]] = []  # (due host ns, copies left, event id, payload)
        self._next_heartbeat = 0

    @property
    def url(self) -> str:
        """``zenoh://HOST:PORT/TABLE`` with the port the session listens on."""
        return self.address.url

    def start(self) -> None:
        """Serve the command and clock queryables and subscribe to the host's setpoints and heartbeats."""
        session = self._session
        self._entities = [
            session.declare_queryable(self._keys["command"], lambda q: self._arrived("command", q, _payload(q))),
            session.declare_queryable(self._keys["clock"], self._clock_query),
            session.declare_queryable(self._keys["bodies"],
                                      lambda q: self._reply(q, self._keys["bodies"], self._bodies_payload)),
            session.declare_subscriber(self._keys["setpoints"],
                                       lambda s: self._arrived("setpoints", None, s.payload.to_bytes())),
            session.declare_subscriber(self._keys["host-heartbeat"],
                                       lambda s: self._arrived("heartbeat", None, s.payload.to_bytes())),
            session.liveliness().declare_token(alive_key(self.address.table, "table")),
        ]

    # ----- receiving (zenoh's threads) ------------------------------------------------------------------

    def _arrived(self, kind: str, query: zenoh.Query | None, payload: bytes) -> None:
        with self._lock:
            now = time.monotonic_ns()
            self.counters.messages_received += 1
            lost = bool(self.loss) and self._rng.random() < self.loss
            if lost:
                self.counters.messages_dropped += 1
            else:
                self._inbox.append((now + self.delay_ns, kind, query, payload))
        if lost and query is not None:
            query.drop()  # ends the host's query without a reply

    def _clock_query(self, query: zenoh.Query) -> None:
        if self.delay_ns:
            self._arrived("clock", query, _payload(query))
            return
        with self._lock:
            self.counters.messages_received += 1
            lost = bool(self.loss) and self._rng.random() < self.loss
            if lost:
                self.counters.messages_dropped += 1
        if lost:
            query.drop()
        else:
            self._answer_clock(query, _payload(query))

    def _answer_clock(self, query: zenoh.Query, payload: bytes) -> None:
        try:
            t_send = decode_clock_request(payload)
        except PayloadError as exc:
            self._reply_error(query, exc)
            return
        with self._lock:
            self.counters.clock_answered += 1
        self._reply(query, self._keys["clock"],
                    encode_clock_reply(ClockReply(t_send, self.clock(time.monotonic_ns()))))

    # ----- the tick thread's side -----------------------------------------------------------------------

    def take(self, now: int) -> list[tuple[int, Action]]:
        """Messages due by host time ``now`` [ns], as (arrival controller time [ns], action on the core)."""
        taken = []
        with self._lock:
            while self._inbox and self._inbox[0][0] <= now:
                taken.append(self._inbox.popleft())
        actions = []
        for due, kind, query, payload in taken:
            arrival = self.clock(due)
            action = self._action(kind, query, payload, arrival, due)
            if action is not None:
                actions.append((arrival, action))
        return actions

    def _action(self, kind: str, query: zenoh.Query | None, payload: bytes, arrival: int,
                heard: int) -> Action | None:
        """The effect of a message that arrived at controller time ``arrival`` (host time ``heard``) [ns]; None when
        it has none."""
        if query is not None:
            if kind == "clock":
                return lambda core: self._answer_clock(query, payload)
            return lambda core: self._command(core, query, payload, arrival, heard)
        if kind == "heartbeat":
            return self._heartbeat_action(payload, arrival, heard)
        return self._chunk_action(payload, arrival, heard)

    def _heartbeat_action(self, payload: bytes, arrival: int, heard: int) -> Action | None:
        """A host heartbeat keeps its claim and feeds the watchdog only when signed and from the table's owner."""
        received = split_signed(payload)
        try:
            decode_heartbeat(received.message)
        except PayloadError:
            self._count("bad_payloads")
            return None
        if self._verifier.verify(self._keys["host-heartbeat"], received) is not Verdict.SIGNED:
            self._count("heartbeats_refused")
            return None
        if not self._ownership.heard(sender_of(received), heard):
            self._count("heartbeats_other_host")
            return None
        return lambda core: core.heartbeat(arrival)

    def _chunk_action(self, payload: bytes, arrival: int, heard: int) -> Action | None:
        if self.stall_chunks:
            self._count("chunks_stalled")
            return None
        try:
            chunk, received = decode_setpoints(payload)
        except PayloadError:
            self._count("bad_payloads")
            return None
        signed = self._verify(self._keys["setpoints"], received)
        if signed and not self._ownership.allows(sender_of(received), heard):
            self._count("chunks_other_host")
            return None

        def play(core: ControllerCore) -> None:
            core.chunk(chunk.seq, chunk.t_start_ns, chunk.spacing_ns, chunk.samples, chunk.end_of_stream, signed,
                       arrival)

        return play

    def _verify(self, key: str, received: Any) -> bool:
        verdict = self._verifier.verify(key, received)
        if verdict is not Verdict.SIGNED:
            self._count(_VERDICT_COUNTERS[verdict])
        return verdict is Verdict.SIGNED

    def _command(self, core: ControllerCore, query: zenoh.Query, payload: bytes, arrival: int, heard: int) -> None:
        try:
            request, received = decode_command(payload)
        except PayloadError as exc:
            self._count("bad_payloads")
            self._reply_error(query, exc)
            return
        signed = self._verify(self._keys["command"], received)
        who = sender_of(received)
        if request.command in ("claim", "release"):
            self._ownership_command(core, query, request.cmd_id, request.command, who, signed, arrival, heard)
            return
        command = Command(request.command)
        known = self._answers.get(request.cmd_id)
        if known is not None and known[0] == received.message and (signed or command not in SIGNED_COMMANDS):
            self._count("duplicate_commands")
            self._reply_answer(query, Answer(request.cmd_id, known[1].value, arrival))
            return
        if signed and command in SIGNED_COMMANDS and not self._saved_replay_state():
            self._reply_answer(query, Answer(request.cmd_id, core.refuse().value, arrival))
            return
        if signed and who is not None and command in SIGNED_COMMANDS:  # a signed payload names its sender
            held = self._ownership.claim(who, _describe(who), heard, time.time())
            if held is not None:
                self._count("commands_other_host")
                self._reply_owner(query, request.cmd_id, held, heard)
                return
        elif signed:
            self._ownership.heard(who, heard)
        result = core.command(command, request.params, signed, arrival)
        if result is not Result.DENIED:
            self._answers[request.cmd_id] = (received.message, result)
            self._answers.move_to_end(request.cmd_id)
            if len(self._answers) > REMEMBERED_COMMANDS:
                self._answers.popitem(last=False)
        if result is Result.IN_PROGRESS:
            self._requesters[command] = request.cmd_id
        self._reply_answer(query, Answer(request.cmd_id, result.value, arrival))

    def _ownership_command(self, core: ControllerCore, query: zenoh.Query, cmd_id: int, name: str, who: int | None,
                           signed: bool, arrival: int, heard: int) -> None:
        """``claim`` or ``release`` (``sim_table.ownership``) from sender ``who`` (None: none in the trailer): refused
        unsigned (``denied``); a refused claim is answered with an OWNER; a release from another sender than the
        owner leaves the claim (``rejected``)."""
        if not signed or who is None or not self._saved_replay_state():
            self._reply_answer(query, Answer(cmd_id, core.refuse().value, arrival))
            return
        if name == "release":
            released = self._ownership.release(who, heard)
            self._reply_answer(query, Answer(cmd_id, (Result.ACCEPTED if released else Result.REJECTED).value,
                                             arrival))
            return
        held = self._ownership.claim(who, _describe(who), heard, time.time())
        if held is not None:
            self._reply_owner(query, cmd_id, held, heard)
            return
        self._reply_answer(query, Answer(cmd_id, Result.ACCEPTED.value, arrival))

    def _reply_owner(self, query: zenoh.Query, cmd_id: int, owner: Owner, heard: int) -> None:
        """Refuse command ``cmd_id`` because ``owner`` owns the table: an OWNER reply."""
        silent_ms = max(0, heard - owner.last_heard_ns) // 1_000_000
        self._reply(query, self._keys["command"], encode_owner(OwnerReport(
            cmd_id, round(owner.since_unix_s * 1000), min(silent_ms, 2**32 - 1), round(OWNER_TIMEOUT * 1000),
            owner.description)))

    def _saved_replay_state(self) -> bool:
        """Write the replay state before a signed motion command takes effect (its stamp must survive a crash);
        whether it is written (or there is no file to write)."""
        if self._store is None or self._store.save():
            return True
        self._count("replay_state_unsaved")
        return False

    def command_done(self, done: Done) -> None:
        """The final answer to a command that was ``in_progress``, published on ``answer``."""
        cmd_id = self._requesters.pop(done.command, None)
        if cmd_id is None:
            return
        if cmd_id in self._answers:
            self._answers[cmd_id] = (self._answers[cmd_id][0], done.result)
        self._publish(self._answer, self._keys["answer"], encode_answer(Answer(cmd_id, done.result.value, done.t_ns)))

    def chunk_refused(self, refused: Refused) -> None:
        """Why a setpoint chunk was refused: a REFUSAL, published reliably on ``refusal``."""
        self._count("refusals_sent")
        self._publish(self._refusal, self._keys["refusal"], encode_refusal(Refusal(refused.t_ns, refused.seq,
                                                                                   refused.reason)))

    def limit_tripped(self, trip: ControllerTrip) -> None:
        """The controller's own level passed: a LIMIT_TRIP, published reliably on ``limit-trip``."""
        self._count("limit_trips_sent")
        self._publish(self._limit_trip, self._keys["limit-trip"], encode_limit_trip(LimitTripReport(
            trip.t_ns, trip.sensor, trip.level.code(), trip.value, trip.level.threshold)))

    def send_status(self, snap: Snapshot) -> None:
        """One STATUS."""
        self._count("status_sent")
        self._publish(self._status, self._keys["status"], encode_status(StatusReport(
            snap.t_ns, snap.state.value, min(snap.buffer_depth, 2**32 - 1), snap.last_chunk_seq, snap.underruns,
            int(snap.faults), snap.refused_commands, snap.pose, snap.buffer_capacity,
            min(snap.samples_late, 2**32 - 1), min(snap.virtual_watchdog_ns // 1_000_000, 2**32 - 1),
            snap.inputs, snap.following_error)))

    def _send_accel(self, batch: Batch) -> None:
        key = table_key(self.address.table, "accel", str(batch.source))
        publisher = self._accel_publishers.get(batch.source)
        if publisher is None:
            publisher = self._accel_publishers[batch.source] = self._session.declare_publisher(
                key, congestion_control=self._batch_congestion)
        self.counters.accel_batches_sent += 1
        self.counters.accel_samples_sent += len(batch.samples)
        self._publish(publisher, key, encode_accel(AccelSamples(batch.source, batch.seq, batch.t_start_ns,
                                                           batch.spacing_ns, batch.samples)))

    def _send_tilt(self, batch: Batch) -> None:
        self.counters.tilt_batches_sent += 1
        self.counters.tilt_samples_sent += len(batch.samples)
        self._publish(self._tilt_publisher, self._keys["tilt"], encode_tilt(TiltSamples(
            batch.source, batch.seq, batch.t_start_ns, batch.spacing_ns, batch.samples)))

    def send_overturn(self, event_id: int, body_id: int, direction: int, tilt: float, t_ns: int) -> None:
        """An overturn event, now and again :data:`EVENT_RESENDS` times."""
        self.counters.overturn_events += 1
        payload = encode_overturn(Overturn(event_id, body_id, direction, tilt, t_ns))
        self._send_overturn(payload)
        heapq.heappush(self._resends, (time.monotonic_ns() + round(EVENT_RESEND_PERIOD * 1e9), EVENT_RESENDS,
                                       event_id, payload))

    def _send_overturn(self, payload: bytes) -> None:
        self.counters.overturn_messages_sent += 1
        self._publish(self._overturn, self._keys["overturn"], payload)

    def service(self, now: int, state: State) -> None:
        """Periodic duties at host time ``now`` [ns]: heartbeat, event resends, delayed messages."""
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + round(HEARTBEAT_PERIOD * 1e9)
            self._publish(self._heartbeat, self._keys["heartbeat"], encode_heartbeat(self.clock(now)))
        while self._resends and self._resends[0][0] <= now:
            due, left, event_id, payload = heapq.heappop(self._resends)
            self._send_overturn(payload)
            if left > 1:
                heapq.heappush(self._resends, (due + round(EVENT_RESEND_PERIOD * 1e9), left - 1, event_id, payload))
        due_now = []
        with self._lock:
            while self._outbox and self._outbox[0][0] <= now:
                due_now.append(heapq.heappop(self._outbox)[2])
        for deliver in due_now:
            deliver()

    # ----- sending ----------------------------------------------------------------------------------------

    def _count(self, name: str) -> None:
        with self._lock:
            setattr(self.counters, name, getattr(self.counters, name) + 1)

    def _publish(self, publisher: zenoh.Publisher, key: str, message: bytes) -> None:
        """Publish ``message`` signed for ``key``, the publisher's key expression."""
        payload = self._signer.sign(key, message)
        self._send(lambda: publisher.put(payload))

    def _reply(self, query: zenoh.Query, key: str, message: bytes) -> None:
        payload = self._signer.sign(key, message)

        def deliver() -> None:
            query.reply(key, payload)
            query.drop()

        self._send(deliver, query.drop)

    def _reply_answer(self, query: zenoh.Query, answer: Answer) -> None:
        self._reply(query, self._keys["command"], encode_answer(answer))

    def _reply_error(self, query: zenoh.Query, error: Exception) -> None:
        def deliver() -> None:
            query.reply_err(str(error).encode())
            query.drop()

        self._send(deliver, query.drop)

    def _send(self, deliver: Callable[[], None], discard: Callable[[], None] | None = None) -> None:
        """Deliver a message through the injected loss (``discard`` instead) and delay."""
        with self._lock:
            lost = bool(self.loss) and self._rng.random() < self.loss
            if lost:
                self.counters.messages_not_sent += 1
            else:
                self.counters.messages_sent += 1
                if self.delay_ns:
                    self._queued += 1
                    heapq.heappush(self._outbox, (time.monotonic_ns() + self.delay_ns, self._queued, deliver,
                                                  discard))
                    return
        if not lost:
            deliver()
        elif discard is not None:
            discard()

    def close(self) -> None:
        """End the queries still held (without a reply) and close the session."""
        for entity in self._entities:
            entity.undeclare()
        with self._lock:
            held = [query.drop for _, _, query, _ in self._inbox if query is not None]
            held += [discard for _, _, _, discard in self._outbox if discard is not None]
            self._inbox.clear()
            self._outbox.clear()
        for discard in held:
            discard()
        with contextlib.suppress(zenoh.ZError):
            self._session.close()
        if self._store is not None:
            self._store.close()

    def rest(self) -> None:
        """Forget every host (`sim_table.endpoint.Rests`): no owner, remembered command, event waiting to be sent,
        no message waiting in the inbox (a query among them ended without a reply), the samples short of a batch
        dropped, every counter zero; the signatures' replay guard kept."""
        with self._lock:
            queries = [query for _, _, query, _ in self._inbox if query is not None]
            discards = [discard for _, _, _, discard in self._outbox if discard is not None]
            self.counters = LinkCounters()
            self._ownership = Ownership(round(OWNER_TIMEOUT * 1e9))
            for kept in (self._inbox, self._outbox, self._answers, self._requesters, self._resends):
                kept.clear()
            self._accel = Batcher(ACCEL_PER_BATCH)
            self._tilt = Batcher(TILT_PER_BATCH)
        for query in queries:
            query.drop()
        for discard in discards:
            discard()

    def counters_dict(self) -> dict[str, int]:
        ownership = self._ownership
        return {**asdict(self.counters), "claims_granted": ownership.claims_granted,
                "claims_refused": ownership.claims_refused, "claim_takeovers": ownership.takeovers}


def _payload(query: zenoh.Query) -> bytes:
    return query.payload.to_bytes() if query.payload is not None else b""


def _listen(address: TableUrl, security: LinkSecurity) -> tuple[zenoh.Session, TableUrl]:
    """A session listening on ``address`` with ``security`` (port 0: a free port), and the address with the port it
    got. :class:`ValueError` for an endpoint ``security`` does not allow (plain text off loopback)."""
    try:
        address._replace(port=address.port or 1).endpoint_for(security)  # port 0: any, probed below
    except EndpointError as exc:
        raise ValueError(f"--listen {address.url}: {exc}") from None
    error: Exception | None = None
    for _ in range(PORT_ATTEMPTS if address.port == 0 else 1):
        port = address.port or _free_port(address.host)
        resolved = address._replace(port=port)
        try:
            config = session_config(listen=[resolved.endpoint_for(security)], security=security)
            return zenoh.open(config), resolved
        except zenoh.ZError as exc:
            error = exc
    raise OSError(f"cannot listen on {address.url}: {error}")


def _free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


def _describe(sender: int) -> str:
    """A host as a refused claimant is told of it: its signing sender id (random per connection)."""
    return f"the zenoh host signing as sender {sender:016x}"


def open_endpoint(url: str, options: EndpointOptions) -> ZenohEndpoint:
    """The endpoint for ``zenoh://HOST:PORT/TABLE`` (port 0: any free port) — `sim_table.endpoint`'s factory."""
    return ZenohEndpoint(parse_table_url(url, any_port=True), options.key, options.clock, loss=options.loss,
                         delay=options.delay, seed=options.seed, virtual_time=options.virtual_time,
                         bodies=options.bodies, security=options.security, replay_state=options.replay_state)
