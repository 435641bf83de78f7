"""The table controller over MAVLink 2 on UDP: ``open_table("mavlink://HOST:PORT", key_file=...)``.

The link is a :class:`protocols.mavlink.UdpLink` to the controller at HOST:PORT, every message **signed** with the
rig's key (``key_file``, else ``$SHAKETABLE_MAVLINK_KEY``) both ways: what the controller sends is taken only when
signed with that key, fresh and not replayed (:func:`protocols.mavlink.parse_guarded`); the rest is dropped and
counted (:meth:`MavlinkTable.link_stats`). A **receive thread** stamps each datagram with its arrival time and
dispatches it (feedback, the waiting command, the clock); a **heartbeat thread** sends HEARTBEAT at
:data:`HEARTBEAT_RATE` [Hz] and a TIMESYNC request every :data:`TIMESYNC_EVERY` heartbeats. Commands are
COMMAND_LONG, resent with ``confirmation`` 1, 2, … until acknowledged; the clock is fitted from TIMESYNC round trips
(:class:`drivers.clock.ClockSync`); streams are SHAKETABLE_SETPOINT_CHUNKs of 8 samples (``drivers.chunked``). A
send the network refuses (:data:`NETWORK_DOWN`) is counted (``send_failures``), not raised.

A command refused TEMPORARILY_REJECTED after a STATUSTEXT of severity ERROR raises
:class:`~drivers.controller.CommandRejectedError` with that text: the controller's reason (an ARM without the
heartbeat kept up).

Each protocol decision and its reasons: docs/transports.md §MAVLink: the host; the controller side is
``sim_table.mavlink_endpoint``.
"""

from __future__ import annotations

import errno
import ipaddress
import secrets
import threading
import time
from collections import deque
from datetime import UTC, datetime
from typing import Any

import numpy as np

from analysis.table.controller_limits import ControllerLevel, ControllerTrip
from analysis.table.model import TableModel
from drivers.bodies import BodyReports, TableBody
from drivers.chunked import MOTION_STATES, ChunkedStreamController, CommandAnswer
from drivers.controller import (
    AccelBatch,
    CommandDeniedError,
    CommandFailedError,
    CommandRejectedError,
    ControllerText,
    Detection,
    SetpointRefusal,
    TableError,
    TableLinkLostError,
    TableStatus,
    TableTimeoutError,
    TiltBatch,
    host_port,
    register_scheme,
    sleep_until,
)
from protocols.mavlink import (
    SETPOINTS_PER_CHUNK,
    UdpLink,
    badly_signed,
    dialect,
    enable_signing,
    follow_wall_clock,
    parse_guarded,
    replay_guard,
    setpoint_chunks,
    unpack_accel_batch,
    unpack_tilt_batch,
    whole_frames,
)
from protocols.replay import Freshness
from protocols.signing_key import load_signing_key

RECEIVE_BUFFER = 4 << 20
"""Requested socket receive buffer [bytes]."""

HEARTBEAT_RATE = 50.0
"""Host heartbeats per second. The controller stops the table after 100 ms without one: at 50 Hz that takes five
lost in a row (at 20 Hz one lost heartbeat left a 100 ms gap, and 5 % loss tripped it within seconds)."""

TIMESYNC_EVERY = 25
"""A TIMESYNC request every this many heartbeats (2 Hz)."""

_STATUS_GRACE_NS = 40_000_000  # a status this long after a motion's ACK (controller time) reflects it


class _AckSlot:
    """COMMAND_ACKs received for one command id while a caller waits: (result, progress, host ns)."""

    def __init__(self) -> None:
        self.acks: list[tuple[int, int, int]] = []


class _AckAnswer(CommandAnswer):
    """A command's first COMMAND_ACK (``result``, received at host time ``host_ns``); the later ACKs of a motion
    arrive in ``slot`` while it stays in the table's ACK slots."""

    def __init__(self, table: MavlinkTable, cmd_id: int, slot: _AckSlot, result: int, host_ns: int) -> None:
        self.table, self.cmd_id, self.slot, self.host_ns = table, cmd_id, slot, host_ns
        self.in_progress = result == table.d.MAV_RESULT_IN_PROGRESS
        self.over_from_ns = table.clock.to_controller(host_ns) + _STATUS_GRACE_NS

    def shown(self, status: TableStatus) -> bool:
        """Received after the ACK: the controller sends a command's answer after the status of the tick it took
        effect in, and a status taken after it next."""
        return status.host_ns > self.host_ns

    def _finals(self) -> list[int]:
        """The final results received (retransmissions may bring more IN_PROGRESS answers)."""
        return [result for result, _, _ in self.slot.acks if result != self.table.d.MAV_RESULT_IN_PROGRESS]

    def reached(self) -> bool | None:
        finals = self._finals()
        return finals[0] == self.table.d.MAV_RESULT_ACCEPTED if finals else None

    def shows_end(self, status: TableStatus) -> bool:
        """Received after the last ACK, out of the motion."""
        return status.host_ns > self.slot.acks[-1][2] and status.state not in MOTION_STATES

    def close(self) -> None:
        if self.table._acks.get(self.cmd_id) is self.slot:  # not a later command's slot for the same id
            self.table._acks.pop(self.cmd_id, None)


class MavlinkTable(ChunkedStreamController):
    """A table controller at ``mavlink://HOST:PORT`` (module docstring).

    Options: ``key_file`` (default ``$SHAKETABLE_MAVLINK_KEY``); ``system``/``component`` this host's MAVLink
    ids; ``target_system``/``target_component`` the controller's; ``link_id`` of the signatures (default: random
    per connection, so that two hosts with the same ids are two signing streams, not one whose timestamps
    interleave and get refused as replays);
    ``command_timeout`` [s] per attempt and ``retries``; ``connect_timeout`` [s]; ``table`` the table model streamed
    trajectories are checked against (default: Table IV and the default hexapod); ``observe`` connect without
    claiming the table (a monitor: ``drivers.chunked``).
    """

    samples_per_chunk = SETPOINTS_PER_CHUNK

    def __init__(self, url: str, *, key_file: str | None = None, system: int = 255, component: int = 190,
                 target_system: int = 1, target_component: int = 1, link_id: int | None = None,
                 command_timeout: float = 0.15, retries: int = 4, connect_timeout: float = 3.0,
                 table: TableModel | None = None, observe: bool = False) -> None:
        super().__init__(url, table, observe)
        self.address = host_port(url)
        self.key_file = key_file
        self.system, self.component = system, component
        self.target = (target_system, target_component)
        self.link_id = link_id
        self.command_timeout = command_timeout
        self.retries = retries
        self.connect_timeout = connect_timeout
        self.d = dialect()
        self._link: UdpLink | None = None
        self._send_lock = threading.Lock()
        self._closing = threading.Event()
        self._threads: list[threading.Thread] = []
        self._acks: dict[int, _AckSlot] = {}
        self._command_locks: dict[int, threading.Lock] = {}
        self._timesync_sent: deque[int] = deque(maxlen=64)
        self._fault_bits = [(bit, entry.name.removeprefix("SHAKETABLE_FAULT_"))  # single bits (not ENUM_END)
                            for bit, entry in self.d.enums["SHAKETABLE_FAULT"].items() if bit & (bit - 1) == 0]
        self._input_bits = [(bit, entry.name.removeprefix("SHAKETABLE_INPUT_").lower())
                            for bit, entry in self.d.enums["SHAKETABLE_INPUT"].items() if bit & (bit - 1) == 0]
        self.last_controller_heartbeat_ns: int | None = None
        self._status_text: tuple[str, int] | None = None
        """The controller's last STATUSTEXT of severity ERROR or worse and when it arrived [host ns]: why it
        refused the command it precedes (an ARM without the heartbeat kept up)."""
        """Host time [ns] of the controller's last HEARTBEAT."""
        self._body_reports = BodyReports()
        self._owner_report: tuple[Any, int] | None = None  # the last SHAKETABLE_OWNER, host ns received
        self.refused = {"junk_datagrams": 0, "refused_unsigned": 0, "refused_bad_signature": 0, "refused_stale": 0,
                        "refused_future": 0}
        """What the receive thread dropped: datagrams that are not whole MAVLink 2 frames, messages without a
        signature, with one that did not verify (another key, altered), with a stale timestamp (replayed or
        reordered within its stream, or opening a stream too far behind) or one too far ahead
        (:mod:`protocols.replay`)."""
        self._guard = replay_guard()
        self.send_failures = 0
        """Datagrams the network did not take (:data:`NETWORK_DOWN`): lost, as UDP loses them."""
        self._send_failure: str | None = None  # the last one's reason

    # ----- connection -----------------------------------------------------------------------------------

    def connect(self) -> None:
        if self._link is not None:
            return
        key = load_signing_key(self.key_file)
        link_id = secrets.randbelow(256) if self.link_id is None else self.link_id
        self.heap.hold()
        host, port = self.address
        local = "127.0.0.1" if _is_loopback(host) else "0.0.0.0"
        self._link = UdpLink.open((local, 0), (host, port), source_system=self.system,
                                  source_component=self.component, key=key, link_id=link_id,
                                  receive_buffer=RECEIVE_BUFFER)
        self._guard = replay_guard()  # the controller's streams, heard afresh on each connection
        self._parser = self.d.MAVLink(None, srcSystem=self.system, srcComponent=self.component)
        self._parser.robust_parsing = True
        enable_signing(self._parser, key, link_id=link_id, sign_outgoing=False)
        self._closing.clear()
        self._threads = [threading.Thread(target=self._receive_loop, name="mavlink-receive", daemon=True),
                         threading.Thread(target=self._heartbeat_loop, name="mavlink-heartbeat", daemon=True)]
        for thread in self._threads:
            thread.start()
        try:
            deadline = time.monotonic() + self.connect_timeout
            while not (self.clock.fitted and self.feedback.latest is not None):
                if time.monotonic() > deadline:
                    self._no_answer()
                self._request_timesync()  # round trips 20 ms apart until the clock's rate is fitted
                time.sleep(0.02)
            self._claim()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        if self._link is None:
            return
        self._release()
        self._closing.set()
        for thread in self._threads:
            thread.join(timeout=1.0)
        self._link.close()
        self._link = None
        self.feedback.close()
        self.heap.release()

    def _receive_loop(self) -> None:
        assert self._link is not None
        sock = self._link.sock
        sock.settimeout(0.2)
        while not self._closing.is_set():
            try:
                data, _ = sock.recvfrom(65535)
            except TimeoutError:
                continue
            except OSError:
                return
            now = time.monotonic_ns()
            for msg in self._verified(data):
                self._dispatch(msg, now)

    def _verified(self, data: bytes) -> list[Any]:
        """The messages of one datagram signed by the controller with the rig's key; the rest counted in
        :attr:`refused`."""
        frames = whole_frames(data)
        if frames is None:
            self.refused["junk_datagrams"] += 1
            return []
        verified = []
        for frame in frames:
            messages, freshness = parse_guarded(self._parser, self._guard, frame)
            if freshness in (Freshness.STALE, Freshness.FUTURE):
                self.refused[f"refused_{freshness.value}"] += 1
                continue
            for msg in messages:
                if msg.get_signed():
                    verified.append(msg)
                else:
                    self.refused["refused_bad_signature" if badly_signed(msg) else "refused_unsigned"] += 1
        return verified

    def _dispatch(self, msg: Any, now: int) -> None:
        kind = msg.get_type()
        if kind == "SHAKETABLE_STATUS":
            self.feedback.publish_status(self._status(msg, now))
        elif kind == "SHAKETABLE_ACCEL_BATCH":
            self._accel(msg)
        elif kind == "SHAKETABLE_TILT_BATCH":
            self._tilt(msg)
        elif kind == "SHAKETABLE_BODY":
            self._body_reports.add(msg.count, TableBody(msg.body_id, msg.b, msg.h, msg.depth, msg.x, msg.y)
                                   if msg.count else None)
        elif kind == "STATUSTEXT":
            severity = self.d.enums["MAV_SEVERITY"][msg.severity].name if msg.severity in self.d.enums[
                "MAV_SEVERITY"] else str(msg.severity)
            self.feedback.publish_controller_text(ControllerText(now, severity.removeprefix("MAV_SEVERITY_"),
                                                                 msg.text))
            if msg.severity <= self.d.MAV_SEVERITY_ERROR:  # why a command that follows is refused
                self._status_text = (_text_of(msg.text), now)
        elif kind == "SHAKETABLE_LIMIT_TRIP":
            self._limit_trip(msg)
        elif kind == "SHAKETABLE_CHUNK_REFUSED":
            self._publish_refusal(SetpointRefusal(msg.t_ns, msg.chunk_seq, msg.reason))
        elif kind == "SHAKETABLE_OVERTURN_EVENT":
            self.feedback.publish_detection(Detection(msg.event_id, msg.body_id, msg.direction, msg.tilt, msg.t_ns))
        elif kind == "COMMAND_ACK":
            slot = self._acks.get(msg.command)
            if slot is not None:
                slot.acks.append((msg.result, msg.progress, now))
                self.feedback.notify()
        elif kind == "TIMESYNC" and msg.tc1 != 0 and msg.ts1 in self._timesync_sent:
            self.clock.add(msg.ts1, now, msg.tc1)
            self.feedback.notify()
        elif kind == "HEARTBEAT":
            self.last_controller_heartbeat_ns = now
        elif kind == "SHAKETABLE_OWNER":
            self._owner_report = (msg, now)

    def _owner_refusal(self) -> str:
        """The owner as the SHAKETABLE_OWNER sent before the refusing ACK names it (the ACK and its SHAKETABLE_OWNER
        leave the controller together; a lost one leaves the owner unnamed)."""
        report = self._owner_report
        if report is None:
            return ("another host (the controller's SHAKETABLE_OWNER did not arrive) since an unknown time; it is "
                    "released when that host disconnects or falls silent")
        msg, _ = report
        since = datetime.fromtimestamp(msg.since_ms / 1000, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
        return (f"{msg.owner_address} (system {msg.owner_system}, component {msg.owner_component}) since {since}, "
                f"last heard {msg.silent_ms / 1000:.2f} s ago (its claim lapses after {msg.timeout_ms / 1000:g} s "
                "of silence, or when it disconnects)")

    def bodies(self, timeout: float = 3.0) -> tuple[TableBody, ...] | None:
        """The bodies in the controller's SHAKETABLE_BODY messages (sent at once to a new host, then every second);
        None if they did not all come within ``timeout`` [s] (a controller that does not send them)."""
        return self._body_reports.wait(timeout)

    def _status(self, msg: Any, now: int) -> TableStatus:
        state = self.d.enums["SHAKETABLE_STATE"][msg.state].name.removeprefix("SHAKETABLE_STATE_").lower()
        faults = tuple(name for bit, name in self._fault_bits if msg.faults & bit)
        return TableStatus(msg.t_ns, state, msg.buffer_depth, msg.last_chunk_seq, msg.underruns, faults,
                           msg.refused_commands, np.array(msg.pose, dtype=np.float64), now, msg.buffer_capacity,
                           msg.samples_late, msg.virtual_watchdog_ms * 1e-3,
                           tuple(name for bit, name in self._input_bits if msg.inputs & bit),
                           np.array(msg.following_error, dtype=np.float64))

    def _limit_trip(self, msg: Any) -> None:
        """A SHAKETABLE_LIMIT_TRIP as a :class:`ControllerTrip` (one whose code packs no level is counted as junk)."""
        try:
            level = ControllerLevel.decode((float(msg.code), float(msg.level)))
        except ValueError:
            self.refused["junk_datagrams"] += 1
            return
        self.feedback.publish_limit_trip(ControllerTrip(msg.t_ns, msg.sensor, float(msg.value), level))

    def _accel(self, msg: Any) -> None:
        series = unpack_accel_batch(msg)
        self._publish_accel(AccelBatch(msg.sensor_id, msg.batch_seq, series.t_start_ns, series.spacing_ns,
                                       series.samples))

    def _tilt(self, msg: Any) -> None:
        series = unpack_tilt_batch(msg)
        self._publish_tilt(TiltBatch(msg.body_id, msg.batch_seq, series.t_start_ns, series.spacing_ns,
                                     series.samples[:, 0]))

    def _heartbeat_loop(self) -> None:
        period = round(1e9 / HEARTBEAT_RATE)
        deadline = time.monotonic_ns()
        beats = 0
        while not self._closing.is_set():
            self._send(self.d.MAVLink_heartbeat_message(self.d.MAV_TYPE_GCS, self.d.MAV_AUTOPILOT_INVALID, 0, 0,
                                                        self.d.MAV_STATE_ACTIVE, 3))
            beats += 1
            if beats % TIMESYNC_EVERY == 0:
                self._request_timesync()
            deadline = max(deadline + period, time.monotonic_ns())
            sleep_until(deadline)

    def _request_timesync(self) -> None:
        now = time.monotonic_ns()
        self._timesync_sent.append(now)
        self._send(self.d.MAVLink_timesync_message(0, now))

    def _send(self, msg: Any) -> None:
        link = self._link
        if link is None:
            raise TableError(f"{self.url}: not connected")
        with self._send_lock:
            follow_wall_clock(link.mav, self._guard)
            try:
                link.send(msg)
            except OSError as exc:
                if exc.errno not in NETWORK_DOWN:
                    raise
                self.send_failures += 1  # a datagram lost: the statuses that stop coming say the link is lost
                self._send_failure = exc.strerror or str(exc)

    def check_link(self) -> None:
        """As the base's; a lost link's message also names the sends the network refused (module docstring)."""
        try:
            super().check_link()
        except TableLinkLostError as exc:
            detail = self._link_lost_detail()
            if not detail:
                raise
            raise TableLinkLostError(f"{exc}{detail}") from None

    def _link_lost_detail(self) -> str:
        """``"; N sends failed: REASON"`` once the network refused a send (empty before)."""
        failure = self._send_failure
        return f"; {self.send_failures} sends failed: {failure}" if failure is not None else ""

    # ----- commands (ChunkedStreamController) ---------------------------------------------------------

    motion_stopped_result = "FAILED"

    def _request(self, name: str, params: tuple[float, float]) -> _AckAnswer:
        """Send MAV_CMD_SHAKETABLE_<NAME> until acknowledged (module docstring); its first ACK unless refused. The
        ACK slot of a command answered IN_PROGRESS stays for its final ACK until the answer is closed."""
        name = name.upper()
        cmd_id = getattr(self.d, f"MAV_CMD_SHAKETABLE_{name}")
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        lock = self._command_locks.setdefault(cmd_id, threading.Lock())
        with lock:
            slot = self._acks[cmd_id] = _AckSlot()
            sent_ns = time.monotonic_ns()
            try:
                for attempt in range(self.retries + 1):
                    self._send(self.d.MAVLink_command_long_message(*self.target, cmd_id, attempt, *values))
                    if self.feedback.wait_for(lambda: bool(slot.acks), self.command_timeout):
                        break
                else:
                    raise TableTimeoutError(f"{name}: no answer from {self.url} after {self.retries + 1} attempts "
                                            f"of {self.command_timeout} s")
                result, _, when = slot.acks.pop(0)
                self._check(name, result, sent_ns)
                if result != self.d.MAV_RESULT_IN_PROGRESS:
                    del self._acks[cmd_id]
                return _AckAnswer(self, cmd_id, slot, result, when)
            except BaseException:
                self._acks.pop(cmd_id, None)
                raise

    def _check(self, name: str, result: int, sent_ns: int) -> None:
        """Raise the refusal ``result`` of command ``name`` sent at host time ``sent_ns`` [ns] means, if any."""
        d = self.d
        if result in (d.MAV_RESULT_ACCEPTED, d.MAV_RESULT_IN_PROGRESS):
            return
        state = self.feedback.latest.state if self.feedback.latest is not None else None
        result_name = d.enums["MAV_RESULT"][result].name if result in d.enums["MAV_RESULT"] else str(result)
        if result == d.MAV_RESULT_DENIED:
            raise CommandDeniedError(name, result_name, state, "missing or bad signature (are host and controller "
                                     "using the same signing key?)")
        if result == d.MAV_RESULT_TEMPORARILY_REJECTED:
            owner = self._owner_report
            if owner is not None and owner[1] >= sent_ns:  # a SHAKETABLE_OWNER came with the refusal
                raise CommandRejectedError(name, result_name, state, f"table in use by {self._owner_refusal()}")
            said = self._status_text
            if said is not None and said[1] >= sent_ns and said[0]:  # the controller said why (STATUSTEXT)
                why = said[0].removeprefix(f"{name} refused: ")
                raise CommandRejectedError(name, result_name, state, why if why != said[0] else
                                           f"the controller says: {why}")
            raise CommandRejectedError(name, result_name, state, "not accepted in this state")
        why = {d.MAV_RESULT_FAILED: "invalid parameters", d.MAV_RESULT_UNSUPPORTED: "unsupported"}.get(
            result, f"result {result_name}")
        raise CommandFailedError(name, result_name, state, why)

    # ----- streaming (ChunkedStreamController) ---------------------------------------------------------

    def _encode_chunk(self, seq: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray,
                      end_of_stream: bool) -> Any:
        (chunk,) = setpoint_chunks(samples, t_start_ns, spacing_ns, seq, end_of_stream=end_of_stream)
        return chunk

    def _send_chunk(self, message: Any) -> None:
        self._send(message)

    # ----- diagnostics ----------------------------------------------------------------------------------

    def link_stats(self) -> dict[str, float | None]:
        """Clock estimate and round trips, accelerometer and body-tilt batches lost, duplicate overturn events
        dropped, what was refused (:attr:`refused`), age of the controller's last heartbeat [s] (None before the
        first)."""
        beat = self.last_controller_heartbeat_ns
        return {**self.clock.stats(), **self.refused, "accel_batches_lost": self.accel_batches_lost,
                "tilt_batches_lost": self.tilt_batches_lost, "send_failures": self.send_failures,
                "duplicate_detections": self.feedback.duplicate_detections,
                "controller_heartbeat_age_s": None if beat is None else (time.monotonic_ns() - beat) * 1e-9}


NETWORK_DOWN = frozenset({errno.ENETUNREACH, errno.EHOSTUNREACH, errno.ENETDOWN, errno.EHOSTDOWN, errno.ECONNREFUSED})
"""``sendto`` errors that mean the network did not take the datagram (no route, interface down, refused)."""


def _is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


register_scheme("mavlink", MavlinkTable)


def _text_of(text: str | bytes) -> str:
    """A STATUSTEXT's text as printable ASCII (pymavlink gives ``str`` or ``bytes``; padding NULs dropped, any other
    control or non-ASCII character as ``?``: it ends up on the operator's terminal)."""
    raw = text.encode("latin-1", "replace") if isinstance(text, str) else bytes(text)
    return "".join(chr(b) if 32 <= b < 127 else "?" for b in raw.rstrip(b"\0")).strip()
