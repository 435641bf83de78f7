"""The emulator's MAVLink 2 side: the controller end of the table link over UDP (``protocols.mavlink``).

A **receive thread** drains the socket, stamps every datagram with the kernel's arrival time (``SO_TIMESTAMPNS``,
converted to the monotonic clock), verifies signatures, answers TIMESYNC at once and queues the rest; the
emulator's tick thread takes the queue in arrival order (:meth:`MavlinkEndpoint.take`, each message an action on
the :class:`ControllerCore` at its arrival time) and sends everything else. Commands (COMMAND_LONG) are answered by
COMMAND_ACK; a retransmission (``confirmation`` > 0 repeating the last command from its host within
:data:`DEDUP_WINDOW` s) is answered, not re-run. ARM, HOME, SET_TILT, START_STREAM and setpoint chunks need a valid,
fresh signature; STOP, DISARM and EMERGENCY_STOP are taken unsigned. One host owns the table at a time
(``sim_table.ownership``); telemetry goes to every signed HEARTBEAT's sender heard within :data:`PEER_TIMEOUT` s; a
drain reads at most :data:`DRAIN_LIMIT` datagrams; ``loss`` and ``delay`` inject faults.

Each protocol decision, its counters and its reasons: docs/transports.md §MAVLink: the controller; the host side is
``drivers.mavlink``.
"""

from __future__ import annotations

import contextlib
import heapq
import math
import select
import socket
import struct
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, cast
from urllib.parse import urlsplit

import numpy as np

from analysis.table.controller_limits import ControllerTrip
from protocols.mavlink import (
    ACCEL_PER_BATCH,
    END_OF_STREAM,
    TILT_PER_BATCH,
    FramingError,
    Series,
    UdpLink,
    dialect,
    enable_signing,
    follow_wall_clock,
    parse_guarded,
    replay_guard,
    signed_with_key,
    unpack_setpoint_chunk,
    whole_frames,
)
from protocols.mavlink.encode import FrameWriter
from protocols.replay import Freshness
from sim_table.arming import STATUS_TEXT_BYTES, heartbeat_problem
from sim_table.controller import SIGNED_COMMANDS, Command, ControllerCore, Done, Refused, Result, Snapshot, State
from sim_table.endpoint import Action, Batch, BatchedTelemetry, Batcher, BodyOnPlate, EndpointOptions
from sim_table.ownership import Owner, Ownership
from sim_table.replay_store import ReplayStore

DEDUP_WINDOW = 1.0
"""How long a command is remembered for recognising its retransmissions [s, real time]."""

PEER_TIMEOUT = 3.0
"""A host that sent no HEARTBEAT for this long no longer gets telemetry, and an owner silent this long (no signed
HEARTBEAT or command) loses its claim on the table [s, real time]."""

HEARTBEAT_PERIOD = 0.05
"""The controller's heartbeat period [s, real time] (20 Hz)."""

BODIES_PERIOD = 1.0
"""The bodies on the plate are sent this often [s, real time] (and at once to a new host)."""

EVENT_RESENDS = 3
"""Overturn events are sent again this many times ..."""

EVENT_RESEND_PERIOD = 0.1
"""... this far apart [s, real time]."""

REFUSAL_REPEATS = 2
"""A SHAKETABLE_CHUNK_REFUSED is sent at once and again with this many of the statuses after it (a lost datagram
does not lose the reason; the fault bit ``SETPOINT_REFUSED`` is in every status anyway)."""

REASON_BYTES = 120
"""SHAKETABLE_CHUNK_REFUSED.reason's length: a longer reason is cut."""

UNPACKED_KEPT = 2
"""The newest setpoint chunks kept unpacked, by payload: the host sends chunk k, then k − 1 again
(``drivers.chunked``), so a copy arrives after the next chunk and is not unpacked again (chunk_seq is in the
payload: only a copy of the same chunk matches)."""

RECEIVE_BUFFER = 4 << 20
"""Requested socket receive buffer [bytes] (the kernel caps it at net.core.rmem_max)."""

MAX_DATAGRAM = 65535

DRAIN_LIMIT = 256

HELD_DATAGRAM = 1472
"""Telemetry frames (statuses, accelerometer and tilt batches) sent one after another go out together in datagrams
of at most this many bytes (an Ethernet MTU's UDP payload: never fragmented), one ``sendto`` for several frames
(each costs the emulator's tick thread ~10 µs), sent before any other message and at the end of every
:meth:`MavlinkEndpoint.service`; not with injected loss or delay, which act on each frame's own datagram."""
"""Most datagrams one :meth:`MavlinkEndpoint.drain` reads (one tick's worth of a host's messages many times over)."""

_NO_FOLLOWING_ERROR = (0.0,) * 6
"""A status's following error when the table reports none."""

_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35) if sys.platform == "linux" else None
"""Linux's socket option (and control-message type) for a nanosecond kernel receive stamp (struct timespec)."""

Host = tuple[tuple[str, int], int, int]
"""A host on the link: its address (IP, port) and MAVLink system and component ids."""

_STAMP_SPACE = socket.CMSG_SPACE(struct.calcsize("ll")) if _SO_TIMESTAMPNS is not None else 0


@dataclass
class LinkCounters:
    """What the endpoint counted (reported at exit)."""

    packets_received: int = 0
    packets_dropped: int = 0  # injected loss, inbound
    packets_sent: int = 0
    packets_not_sent: int = 0  # injected loss, outbound
    bad_data: int = 0
    junk_datagrams: int = 0  # not whole MAVLink 2 frames: dropped unparsed
    stale_signatures: int = 0  # not above its stream's last stamp, or a new stream too far behind (a replay)
    future_signatures: int = 0  # stamped too far ahead of the current stamp
    replay_state_unsaved: int = 0  # motion commands refused: the replay state could not be written first
    heartbeats_refused: int = 0  # unsigned or badly signed host heartbeats
    heartbeats_other_host: int = 0  # signed, from another host than the table's owner
    arms_refused_heartbeat: int = 0  # signed ARMs refused: the sender's heartbeat not kept up (sim_table.arming)
    commands_other_host: int = 0  # signed motion commands refused: another host owns the table
    chunks_other_host: int = 0  # signed setpoint chunks dropped: another host owns the table
    timesync_answered: int = 0
    duplicate_commands: int = 0
    unsupported_commands: int = 0
    bad_chunks: int = 0
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


KERNEL_STAMPS_WAIT = 2.0
"""Longest wait for the kernel to start stamping datagrams as they arrive [s, real time] (:func:`_await_kernel_stamps`;
past it, the datagrams that came before are stamped when read)."""


def _enable_kernel_stamps(sock: socket.socket) -> None:
    """Ask for the kernel's receive stamp on every datagram of ``sock`` where the platform gives one (without it,
    :meth:`MavlinkEndpoint._arrival` stamps a datagram when it is read), and wait until the kernel gives it."""
    if _SO_TIMESTAMPNS is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            _await_kernel_stamps()


def _stamp_of(ancillary: list[tuple[int, int, bytes]]) -> int | None:
    """The kernel's receive stamp [ns, real-time clock] among a datagram's control messages, if there is one."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(data) >= struct.calcsize("ll"):
            seconds, nanoseconds = struct.unpack_from("ll", data)
            return seconds * 1_000_000_000 + nanoseconds
    return None


def _await_kernel_stamps() -> bool:
    """Wait until the kernel stamps datagrams when they arrive; whether it does (False after
    :data:`KERNEL_STAMPS_WAIT` s, or without a loopback interface).

    Linux stamps arriving packets only while some socket of the machine asks for stamps, and the first one to ask
    turns the stamping on from a kernel worker thread, later: a datagram that arrives before gets, when read, the
    time of the read (``__sock_recv_timestamp``: "race occurred between timestamp enabling and packet receiving").
    On a loaded machine that thread can wait long enough for a host's first datagrams to count when they are read
    (a stall: late), not when they came (tests/emulator/test_mavlink_endpoint.py). So a datagram is sent to a probe
    socket that asks for stamps, until one comes stamped before it was read."""
    if _SO_TIMESTAMPNS is None:
        return False
    deadline = time.monotonic() + KERNEL_STAMPS_WAIT
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            probe.bind(("127.0.0.1", 0))
            probe.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            while True:
                sender.sendto(b"", probe.getsockname())
                if select.select([probe], [], [], KERNEL_STAMPS_WAIT)[0]:
                    read_at = time.time_ns()
                    _, ancillary, _, _ = probe.recvmsg(1, _STAMP_SPACE)
                    stamp = _stamp_of(ancillary)
                    if stamp is not None and stamp < read_at:  # stamped on arrival, not by the read
                        return True
                if time.monotonic() >= deadline:
                    return False
                time.sleep(0.001)
    except OSError:
        return False


class MavlinkEndpoint(BatchedTelemetry):
    """The controller's UDP endpoint at ``local`` (host, port; port 0 = any free one).

    ``key`` (32 bytes) verifies the host's signatures and signs what the controller sends; ``clock`` maps host
    monotonic ns to controller ns; ``system``/``component`` are the controller's MAVLink ids; ``loss``
    (probability) and ``delay`` [s] inject faults with ``seed``; ``bodies`` the specimens on the plate (sent as
    SHAKETABLE_BODY); ``replay_state`` the file that keeps the signatures' stamps across restarts
    (``sim_table.replay_store``; None: kept in memory only). :class:`~sim_table.replay_store.ReplayStateError` when
    that file cannot be trusted.
    """

    def __init__(self, local: tuple[str, int], key: bytes, clock: Callable[[int], int], *, system: int = 1,
                 component: int = 1, loss: float = 0.0, delay: float = 0.0, seed: int = 0,
                 bodies: tuple[BodyOnPlate, ...] = (), replay_state: Path | None = None) -> None:
        if not (0.0 <= loss < 1.0 and delay >= 0.0 and math.isfinite(delay)):
            raise ValueError(f"loss must be in [0, 1) and delay >= 0 s, got {loss!r}, {delay!r}")
        self.d = dialect()
        self.clock = clock
        self.loss = loss
        self.delay_ns = round(delay * 1e9)
        self.counters = LinkCounters()
        self.stall_chunks = False
        """Set by the owner to drop every setpoint chunk from then on (injected stalled stream)."""
        self._rng = np.random.default_rng(seed)
        self._store = ReplayStore(replay_state, "mavlink") if replay_state is not None else None
        self._guard = replay_guard(self._store.load() if self._store is not None else None)
        self._link = UdpLink.open(local, source_system=system, source_component=component,
                                  receive_buffer=RECEIVE_BUFFER)
        self._parser = self.d.MAVLink(None, srcSystem=system, srcComponent=component)
        self._parser.robust_parsing = True
        enable_signing(self._parser, key, link_id=0, sign_outgoing=False)
        enable_signing(self._link.mav, key, link_id=0, timestamp=self._guard.current())
        self._writer = FrameWriter(self._link.mav)
        self._states = {state: getattr(self.d, f"SHAKETABLE_STATE_{state.name}") for state in State}
        if self._store is not None:
            self._store.keep(self._guard)
        _enable_kernel_stamps(self._link.sock)
        self._receive_lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._inbox: deque[tuple[int, int, tuple[str, int], Any, bool]] = deque()
        self._inbox_lock = threading.Lock()
        self._outbox: list[tuple[int, int, bytes, tuple[str, int]]] = []  # delayed datagrams (due, n, data, addr)
        self._unpacked: deque[tuple[bytes, Series]] = deque(maxlen=UNPACKED_KEPT)  # newest chunks' payloads, unpacked
        self._held = bytearray()  # telemetry frames not yet sent (HELD_DATAGRAM) ...
        self._held_to: list[tuple[str, int]] = []  # ... and where they go
        self._sent = 0
        self._peers: dict[tuple[str, int], int] = {}  # address -> host ns of its last signed heartbeat
        # (address, system, component) -> watchdog times [ns] of its previous and last signed heartbeat
        self._beats: dict[tuple[tuple[str, int], int, int], tuple[int | None, int | None]] = {}
        self._ownership = Ownership(round(PEER_TIMEOUT * 1e9))  # owners are (address, system, component)
        self._last: dict[tuple[tuple[str, int], int, int], tuple[int, tuple[float, ...], Result, int]] = {}  # per
        # host (address, system, component)
        self._requesters: dict[Command, tuple[tuple[str, int], int, int]] = {}
        self._answers: list[tuple[Any, tuple[str, int]]] = []  # COMMAND_ACKs held until the batch's statuses are out
        self._accel = Batcher(ACCEL_PER_BATCH)
        self._tilt = Batcher(TILT_PER_BATCH)
        self._resends: list[tuple[int, int, int, Any]] = []  # (due host ns, copies left, event id, message)
        self._refusals: list[tuple[Any, int]] = []  # (SHAKETABLE_CHUNK_REFUSED, copies left to send with statuses)
        self._next_heartbeat = 0
        self._bodies = bodies
        self._next_bodies = 0
        self._commands = {getattr(self.d, f"MAV_CMD_SHAKETABLE_{c.name}"): c for c in Command}
        self._command_ids = {c: cmd_id for cmd_id, c in self._commands.items()}
        self._results = {Result.ACCEPTED: self.d.MAV_RESULT_ACCEPTED, Result.IN_PROGRESS: self.d.MAV_RESULT_IN_PROGRESS,
                         Result.DENIED: self.d.MAV_RESULT_DENIED, Result.FAILED: self.d.MAV_RESULT_FAILED,
                         Result.REJECTED: self.d.MAV_RESULT_TEMPORARILY_REJECTED,
                         Result.CANCELLED: self.d.MAV_RESULT_FAILED}  # common.xml has no CANCELLED any more
        self._closing = False
        self._thread = threading.Thread(target=self._receive_loop, name="mavlink-receive", daemon=True)

    def start(self) -> None:
        """Start receiving (datagrams that came since the socket was bound wait in its buffer)."""
        self._thread.start()

    @property
    def url(self) -> str:
        """``mavlink://HOST:PORT`` with the port the socket got."""
        return f"mavlink://{self.address[0]}:{self.address[1]}"

    @property
    def address(self) -> tuple[str, int]:
        """The (host, port) the endpoint listens on."""
        return self._link.local_address

    # ----- receiving (receive thread) -------------------------------------------------------------------

    def _receive_loop(self) -> None:
        sock = self._link.sock
        while not self._closing:
            try:
                readable, _, _ = select.select([sock], [], [], 0.2)
            except (OSError, ValueError):  # closed
                return
            if readable:
                self.drain()

    def drain(self) -> None:
        """Receive every datagram waiting in the socket, each stamped with its arrival time (module docstring),
        and queue its messages (either thread; one at a time), at most :data:`DRAIN_LIMIT` datagrams."""
        sock = self._link.sock
        with self._receive_lock:
            for _ in range(DRAIN_LIMIT):
                if self._closing:
                    return
                try:
                    if not select.select([sock], [], [], 0)[0]:
                        return
                    data, ancillary, _, source = sock.recvmsg(MAX_DATAGRAM, _STAMP_SPACE)
                except (OSError, ValueError):  # closed
                    return
                now = self._arrival(ancillary)
                self.counters.packets_received += 1
                if self.loss and self._rng.random() < self.loss:
                    self.counters.packets_dropped += 1
                    continue
                for msg in self._parse(data):
                    self._arrived(msg, source, now)

    def _arrival(self, ancillary: list[tuple[int, int, bytes]]) -> int:
        """Host monotonic time [ns] at which a datagram with these control messages reached the socket: the
        kernel's real-time stamp moved onto the monotonic clock (never later than now), else now."""
        now = time.monotonic_ns()
        stamp = _stamp_of(ancillary)
        return now if stamp is None else min(now, stamp - (time.time_ns() - now))

    def _parse(self, data: bytes) -> list[Any]:
        """The messages of one datagram, signatures checked (flagged, not dropped: stopping needs none)."""
        frames = whole_frames(data)
        if frames is None:
            self.counters.junk_datagrams += 1
            return []
        messages = []
        for frame in frames:
            parsed, freshness = parse_guarded(self._parser, self._guard, frame)
            self.counters.stale_signatures += freshness is Freshness.STALE
            self.counters.future_signatures += freshness is Freshness.FUTURE
            if not parsed:
                self.counters.bad_data += 1
            messages += parsed
        return messages

    def _arrived(self, msg: Any, source: tuple[str, int], now: int) -> None:
        kind = msg.get_type()
        if kind == "TIMESYNC" and msg.tc1 == 0 and not self.delay_ns:
            self._answer_timesync(msg, source, now)
            return
        if kind == "HEARTBEAT" and signed_with_key(msg):
            with self._send_lock:
                if source not in self._peers:
                    self._next_bodies = 0  # a new host learns the bodies at once
                self._peers[source] = now
        due = now + self.delay_ns
        with self._inbox_lock:
            self._inbox.append((due, self.clock(due), source, msg, signed_with_key(msg)))

    def _answer_timesync(self, msg: Any, source: tuple[str, int], now: int) -> None:
        self.counters.timesync_answered += 1
        self._send(self.d.MAVLink_timesync_message(self.clock(now), msg.ts1), [source])

    # ----- the tick thread's side -----------------------------------------------------------------------

    def take(self, now: int) -> list[tuple[int, Action]]:
        """Messages due by host time ``now`` [ns], as (arrival controller time [ns], action on the core), after
        draining the socket (what came while this thread was not running is not left behind)."""
        self.drain()
        taken = []
        with self._inbox_lock:
            while self._inbox and self._inbox[0][0] <= now:
                taken.append(self._inbox.popleft())
        actions = []
        for heard, arrival, source, msg, signed in taken:
            action = self._action(msg, source, signed, arrival, heard)
            if action is not None:
                actions.append((arrival, action))
        return actions

    def _action(self, msg: Any, source: tuple[str, int], signed: bool, arrival: int, heard: int) -> Action | None:
        """The effect of ``msg`` from ``source`` that arrived at controller time ``arrival`` (host time ``heard``)
        [ns]; None when it has none."""
        kind = msg.get_type()
        who = (source, msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "HEARTBEAT":
            return self._heartbeat_action(who, signed, arrival, heard)
        if kind == "TIMESYNC" and msg.tc1 == 0:
            return lambda core: self._answer_timesync(msg, source, time.monotonic_ns())
        if kind == "COMMAND_LONG":
            return lambda core: self._command(core, msg, who, signed, arrival, heard)
        if kind == "SHAKETABLE_SETPOINT_CHUNK":
            if signed and not self._ownership.allows(who, heard):
                self.counters.chunks_other_host += 1
                return None
            return self._chunk_action(msg, signed, arrival)
        return None

    def _heartbeat_action(self, who: Host, signed: bool, arrival: int, heard: int) -> Action | None:
        """A host heartbeat keeps its claim and feeds the watchdog only when signed and from the table's owner."""
        if not signed:
            self.counters.heartbeats_refused += 1
            return None
        owns = self._ownership.heard(who, heard)
        if not owns:
            self.counters.heartbeats_other_host += 1

        def beat(core: ControllerCore) -> None:
            self._beats[who] = (self._beats.get(who, (None, None))[1], core.link_time(arrival))  # sim_table.arming
            if owns:
                core.heartbeat(arrival)

        return beat

    def _chunk_action(self, msg: Any, signed: bool, arrival: int) -> Action | None:
        if self.stall_chunks:
            self.counters.chunks_stalled += 1
            return None
        payload = msg.get_payload()
        series = next((kept for known, kept in self._unpacked if known == payload), None)
        if series is None:  # not a copy of a chunk just unpacked (UNPACKED_KEPT)
            try:
                series = unpack_setpoint_chunk(msg)
            except FramingError:
                self.counters.bad_chunks += 1
                return None
            self._unpacked.append((payload, series))
        end = bool(msg.flags & END_OF_STREAM)

        def play(core: ControllerCore) -> None:
            core.chunk(msg.chunk_seq, series.t_start_ns, series.spacing_ns, series.samples, end, signed, arrival)

        return play

    def _command(self, core: ControllerCore, msg: Any, who: Host, signed: bool, arrival: int, heard: int) -> None:
        source, *ids = who
        sender = (ids[0], ids[1])
        if msg.command in (self.d.MAV_CMD_SHAKETABLE_CLAIM, self.d.MAV_CMD_SHAKETABLE_RELEASE):
            self._ownership_command(core, msg, who, signed, heard)
            return
        command = self._commands.get(msg.command)
        if command is None:
            if signed:
                self.counters.unsupported_commands += 1
                self._ack(msg.command, self.d.MAV_RESULT_UNSUPPORTED, 0, source, sender)
            else:
                self._ack(msg.command, self._results[core.refuse()], 0, source, sender)
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        now = time.monotonic_ns()
        last = self._last.get(who)
        if (msg.confirmation > 0 and last is not None and last[:2] == (msg.command, params)
                and now - last[3] <= DEDUP_WINDOW * 1e9 and (signed or command not in SIGNED_COMMANDS)):
            self.counters.duplicate_commands += 1
            self._ack(msg.command, self._results[last[2]], 0, source, sender)
            return
        if signed and command in SIGNED_COMMANDS and not self._saved_replay_state():
            self._ack(msg.command, self._results[core.refuse()], 0, source, sender)
            return
        if signed and command in SIGNED_COMMANDS:
            held = self._ownership.claim(who, _describe(who), heard, time.time())
            if held is not None:
                self.counters.commands_other_host += 1
                self._refuse_for_owner(msg.command, held, who, heard)
                return
        elif signed:
            self._ownership.heard(who, heard)
        if command is Command.ARM and signed:
            problem = heartbeat_problem(self._beats.get(who, (None, None)), core.link_time(arrival), core.watchdog_ns)
            if problem is not None:
                self.counters.arms_refused_heartbeat += 1
                text = problem.encode("ascii")[:STATUS_TEXT_BYTES]
                self._answers.append((self.d.MAVLink_statustext_message(self.d.MAV_SEVERITY_ERROR, text), source))
                self._ack(msg.command, self.d.MAV_RESULT_TEMPORARILY_REJECTED, 0, source, sender)
                return
        result = core.command(command, params, signed, arrival)
        if result is not Result.DENIED:
            self._last[who] = (msg.command, params, result, now)
        if result is Result.IN_PROGRESS:
            self._requesters[command] = (source, *sender)
        self._ack(msg.command, self._results[result], 0, source, sender)

    def _ownership_command(self, core: ControllerCore, msg: Any, who: Host, signed: bool, heard: int) -> None:
        """CLAIM or RELEASE (``sim_table.ownership``): refused unsigned; a refused CLAIM is told who owns the table
        (SHAKETABLE_OWNER, then the COMMAND_ACK); a RELEASE from another host than the owner leaves the claim."""
        source, system, component = who
        if not signed or not self._saved_replay_state():
            self._ack(msg.command, self._results[core.refuse()], 0, source, (system, component))
            return
        if msg.command == self.d.MAV_CMD_SHAKETABLE_RELEASE:
            released = self._ownership.release(who, heard)
            result = Result.ACCEPTED if released else Result.REJECTED
            self._ack(msg.command, self._results[result], 0, source, (system, component))
            return
        held = self._ownership.claim(who, _describe(who), heard, time.time())
        if held is not None:
            self._refuse_for_owner(msg.command, held, who, heard)
            return
        self._ack(msg.command, self.d.MAV_RESULT_ACCEPTED, 0, source, (system, component))

    def _refuse_for_owner(self, command: int, owner: Owner, who: Host, heard: int) -> None:
        """Refuse ``command`` of ``who`` because ``owner`` owns the table: a SHAKETABLE_OWNER, then the
        COMMAND_ACK (TEMPORARILY_REJECTED), both held with the batch's answers."""
        (address, port), system, component = cast(Host, owner.who)
        silent_ms = max(0, heard - owner.last_heard_ns) // 1_000_000
        source, *sender = who
        self._answers.append((self.d.MAVLink_shaketable_owner_message(
            round(owner.since_unix_s * 1000), min(silent_ms, 2**32 - 1), round(PEER_TIMEOUT * 1000), system,
            component, f"{address}:{port}".encode("ascii", "replace")[:64]), source))
        self._ack(command, self.d.MAV_RESULT_TEMPORARILY_REJECTED, 0, source, (sender[0], sender[1]))

    def _saved_replay_state(self) -> bool:
        """Write the replay state before a signed motion command takes effect (its stamp must survive a crash);
        whether it is written (or there is no file to write)."""
        if self._store is None or self._store.save():
            return True
        self.counters.replay_state_unsaved += 1
        return False

    def command_done(self, done: Done) -> None:
        """The final answer to a command that was IN_PROGRESS."""
        requester = self._requesters.pop(done.command, None)
        if requester is None:
            return
        source, system, component = requester
        cmd_id = self._command_ids[done.command]
        last = self._last.get(requester)
        if last is not None and last[0] == cmd_id:
            self._last[requester] = (cmd_id, last[1], done.result, last[3])
        self._ack(cmd_id, self._results[done.result], 100, source, (system, component))

    def _ack(self, command: int, result: int, progress: int, source: tuple[str, int], sender: tuple[int, int]) -> None:
        self._answers.append((self.d.MAVLink_command_ack_message(command, result, progress, 0, *sender), source))

    def send_answers(self) -> bool:
        """Send the COMMAND_ACKs of the batch just run (held until its statuses went out: a status showing what a
        command did precedes its answer); whether there were any."""
        answers, self._answers = self._answers, []
        for message, source in answers:
            self._send(message, [source])
        return bool(answers)

    def send_status(self, snap: Snapshot) -> None:
        """One SHAKETABLE_STATUS to the peers, its frame written directly (``protocols.mavlink.encode``); then the
        refusals still to be repeated."""
        self.counters.status_sent += 1
        self._send_frame(hold=True, write=lambda: self._writer.status(
            snap.t_ns, self._states[snap.state], min(snap.buffer_depth, 65535), snap.last_chunk_seq, snap.underruns,
            int(snap.faults), snap.refused_commands, snap.pose.tolist(), snap.buffer_capacity,
            min(snap.samples_late, 2**32 - 1), min(snap.virtual_watchdog_ns // 1_000_000, 2**32 - 1), snap.inputs,
            _NO_FOLLOWING_ERROR if snap.following_error is None else [float(v) for v in snap.following_error]))
        pending, self._refusals = self._refusals, []
        for message, left in pending:
            self._send(message)
            if left > 1:
                self._refusals.append((message, left - 1))

    def chunk_refused(self, refused: Refused) -> None:
        """A SHAKETABLE_CHUNK_REFUSED saying why, now and with the next :data:`REFUSAL_REPEATS` statuses."""
        self.counters.refusals_sent += 1
        reason = refused.reason.encode("ascii", "replace")[:REASON_BYTES]
        message = self.d.MAVLink_shaketable_chunk_refused_message(refused.t_ns, refused.seq, reason)
        self._send(message)
        self._refusals.append((message, REFUSAL_REPEATS))

    def limit_tripped(self, trip: ControllerTrip) -> None:
        """A SHAKETABLE_LIMIT_TRIP (the controller's own level passed), now and with the next
        :data:`REFUSAL_REPEATS` statuses."""
        self.counters.limit_trips_sent += 1
        message = self.d.MAVLink_shaketable_limit_trip_message(trip.t_ns, trip.value, trip.level.threshold,
                                                               trip.level.code(), trip.sensor)
        self._send(message)
        self._refusals.append((message, REFUSAL_REPEATS))

    def _send_accel(self, batch: Batch) -> None:
        """One SHAKETABLE_ACCEL_BATCH, its frame written directly (``protocols.mavlink.encode``)."""
        self.counters.accel_batches_sent += 1
        self.counters.accel_samples_sent += len(batch.samples)
        self._send_frame(hold=True, write=lambda: self._writer.accel_batch(
            batch.samples, batch.source, batch.t_start_ns, batch.spacing_ns, batch.seq))

    def _send_tilt(self, batch: Batch) -> None:
        """One SHAKETABLE_TILT_BATCH, its frame written directly (``protocols.mavlink.encode``)."""
        self.counters.tilt_batches_sent += 1
        self.counters.tilt_samples_sent += len(batch.samples)
        self._send_frame(hold=True, write=lambda: self._writer.tilt_batch(
            batch.samples, batch.source, batch.t_start_ns, batch.spacing_ns, batch.seq))

    def send_overturn(self, event_id: int, body_id: int, direction: int, tilt: float, t_ns: int) -> None:
        """An overturn event, now and again :data:`EVENT_RESENDS` times."""
        self.counters.overturn_events += 1
        msg = self.d.MAVLink_shaketable_overturn_event_message(event_id, body_id, direction, tilt, t_ns)
        self.counters.overturn_messages_sent += 1
        self._send(msg)
        heapq.heappush(self._resends, (time.monotonic_ns() + round(EVENT_RESEND_PERIOD * 1e9), EVENT_RESENDS,
                                       event_id, msg))

    def service(self, now: int, state: State) -> None:
        """Periodic duties at host time ``now`` [ns]: heartbeat, event resends, delayed datagrams."""
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + round(HEARTBEAT_PERIOD * 1e9)
            self._send(self.d.MAVLink_heartbeat_message(self.d.MAV_TYPE_GENERIC, self.d.MAV_AUTOPILOT_INVALID, 0,
                                                        self._states[state],
                                                        self.d.MAV_STATE_ACTIVE, 3))
        if now >= self._next_bodies:
            self._next_bodies = now + round(BODIES_PERIOD * 1e9)
            self._send_bodies()
        while self._resends and self._resends[0][0] <= now:
            due, left, event_id, msg = heapq.heappop(self._resends)
            self.counters.overturn_messages_sent += 1
            self._send(msg)
            if left > 1:
                heapq.heappush(self._resends, (due + round(EVENT_RESEND_PERIOD * 1e9), left - 1, event_id, msg))
        with self._send_lock:
            self._send_held()
            while self._outbox and self._outbox[0][0] <= now:
                _, _, data, addr = heapq.heappop(self._outbox)
                self._sendto(data, addr)

    def _send_bodies(self) -> None:
        """A SHAKETABLE_BODY per body on the plate (one with count 0 when there is none)."""
        count = len(self._bodies)
        if not count:
            self._send(self.d.MAVLink_shaketable_body_message(0, 0, 0.0, 0.0, 0.0, 0.0, 0.0))
        for body_id, body in enumerate(self._bodies):
            self._send(self.d.MAVLink_shaketable_body_message(body_id, count, body.b, body.h, body.depth, body.x,
                                                              body.y))

    def _send(self, msg: Any, to: list[tuple[str, int]] | None = None) -> None:
        """Frame ``msg`` (pymavlink's ``pack``) and send it to ``to`` (default: the live peers), through the
        injected loss and delay."""
        self._send_frame(lambda: cast(bytes, msg.pack(self._link.mav)), to)

    def _send_frame(self, write: Callable[[], bytes], to: list[tuple[str, int]] | None = None, *,
                    hold: bool = False) -> None:
        """Send the frame ``write`` makes (on the link's sequence number and signing stamps; only when there is
        someone to send it to) to ``to`` (default: the live peers), through the injected loss and delay; ``hold``:
        a telemetry frame, sent with those after it (:data:`HELD_DATAGRAM`)."""
        with self._send_lock:
            if to is None:
                limit = time.monotonic_ns() - round(PEER_TIMEOUT * 1e9)
                to = [addr for addr, seen in self._peers.items() if seen >= limit]
            if not to:
                return
            follow_wall_clock(self._link.mav, self._guard)
            data = write()
            self._link.mav.seq = (self._link.mav.seq + 1) % 256
            if hold and not self.loss and not self.delay_ns:
                if to != self._held_to or len(self._held) + len(data) > HELD_DATAGRAM:
                    self._send_held()
                self._held += data
                self._held_to = to
                return
            self._send_held()
            for addr in to:
                if self.loss and self._rng.random() < self.loss:
                    self.counters.packets_not_sent += 1
                elif self.delay_ns:
                    self._sent += 1
                    heapq.heappush(self._outbox, (time.monotonic_ns() + self.delay_ns, self._sent, data, addr))
                else:
                    self._sendto(data, addr)

    def _send_held(self) -> None:
        """Send the telemetry frames held (under the send lock)."""
        if self._held:
            data = bytes(self._held)
            self._held.clear()
            for addr in self._held_to:
                self._sendto(data, addr)

    def flush_accel(self) -> None:
        """Send the samples still short of a full batch, and every frame held."""
        super().flush_accel()
        with self._send_lock:
            self._send_held()

    def flush_tilt(self) -> None:
        """Send the angles still short of a full batch, and every frame held."""
        super().flush_tilt()
        with self._send_lock:
            self._send_held()

    def _sendto(self, data: bytes, addr: tuple[str, int]) -> None:
        try:
            self._link.sock.sendto(data, addr)
        except OSError:  # a host that went away (ICMP unreachable) is not our failure
            return
        self.counters.packets_sent += 1

    def close(self) -> None:
        """Stop the receive thread and close the socket."""
        self._closing = True
        with self._send_lock:
            self._send_held()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
        self._link.close()
        if self._store is not None:
            self._store.close()

    def rest(self) -> None:
        """Forget every host (`sim_table.endpoint.Rests`): no owner, peer, remembered command, answer or event
        waiting to be sent, no message waiting in the inbox, the samples short of a batch dropped, every counter
        zero; the signatures' replay guard kept."""
        with self._receive_lock, self._send_lock, self._inbox_lock:
            self.counters = LinkCounters()
            self._ownership = Ownership(round(PEER_TIMEOUT * 1e9))
            for kept in (self._inbox, self._outbox, self._peers, self._beats, self._last, self._requesters,
                         self._answers, self._resends, self._refusals, self._held, self._held_to):
                kept.clear()
            self._accel = Batcher(ACCEL_PER_BATCH)
            self._tilt = Batcher(TILT_PER_BATCH)
            self._next_bodies = 0
            self._unpacked.clear()

    def counters_dict(self) -> dict[str, int]:
        ownership = self._ownership
        return {**asdict(self.counters), "claims_granted": ownership.claims_granted,
                "claims_refused": ownership.claims_refused, "claim_takeovers": ownership.takeovers}


def _describe(who: Host) -> str:
    """A host as a refused claimant is told of it: ``127.0.0.1:41234 (system 255, component 190)``."""
    (address, port), system, component = who
    return f"{address}:{port} (system {system}, component {component})"


def open_endpoint(url: str, options: EndpointOptions) -> MavlinkEndpoint:
    """The endpoint for ``mavlink://HOST:PORT`` (port 0: any free port) — `sim_table.endpoint`'s factory."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "mavlink" or port is None or not parts.hostname:
        raise ValueError(f"--listen {url!r}: expected mavlink://HOST:PORT (port 0: any free port)")
    return MavlinkEndpoint((parts.hostname, port), options.key, options.clock, loss=options.loss,
                           delay=options.delay, seed=options.seed, bodies=options.bodies,
                           replay_state=options.replay_state)
