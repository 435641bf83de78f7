"""The transports whose controller buffers setpoints (MAVLink, zenoh): their commands, written once over a small
request hook, and streaming by timestamped setpoint chunks sent ahead of the controller's clock.

As python-can's ``BusABC`` writes ``recv`` once over a backend's ``_recv_internal``,
:class:`ChunkedStreamController` writes ARM, DISARM, HOME, SET_TILT, STOP, EMERGENCY_STOP and START_STREAM once over
:meth:`ChunkedStreamController._request` (send a command, named in lower case with two float parameters, until the
controller answers; return the :class:`CommandAnswer`); a command returns once a status shows what it did
(:data:`STATUS_TIMEOUT` [s]). ``connect`` ends with a CLAIM (:meth:`~ChunkedStreamController._claim`; another live
host's table: :class:`TableInUseError`) unless ``observe=True``; ``close`` starts with a RELEASE. A stream is
START_STREAM with the next chunk number (below :data:`FIRST_SEQ_LIMIT`), then chunks of ``samples_per_chunk`` poses
sent ``lead`` [s] ahead of their first sample in controller time [ns], never more than :data:`AHEAD_NS` [ns] ahead
of the latest status, each sent twice and the last one again every :data:`RESEND_S` [s] until taken. A backend says
how to encode a chunk and send it.

Commands, claims and the stream's pacing, copies and resends with the reasons for each: docs/transports.md §What
both hosts share.
"""

from __future__ import annotations

import contextlib
import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, NoReturn

import numpy as np

from analysis.table.controller_limits import CLEAR_CODE, ControllerLevel
from analysis.table.model import TableModel
from drivers.clock import ClockSync
from drivers.controller import (
    DEFAULT_LEAD,
    STATUS_TIMEOUT,
    STOPPED_STATES,
    TILT_AXES,
    AccelBatch,
    CommandFailedError,
    CommandRefusedError,
    CommandRejectedError,
    SetpointRefusal,
    StreamAbortedError,
    StreamReport,
    TableController,
    TableError,
    TableInUseError,
    TableStatus,
    TableTimeoutError,
    TiltBatch,
    playable_poses,
    sample_spacing,
)

FIRST_SEQ_LIMIT = 2**24
"""Chunk numbers stay below this (exact in START_STREAM's float parameter)."""

AHEAD_NS = 250_000_000
"""A chunk waits until a status shows the controller within ``lead`` + this [ns, controller time] of its first
sample (module docstring): statuses may be this late before the bound delays a real-time stream."""


RESEND_S = 0.1
"""The host waits in slices of this [s], the link checked between them; after each, if no status shows the chunk it
sent last taken, it sends that chunk again (module docstring)."""

REFUSAL_WAIT = 0.5
"""A stream stopped with ``SETPOINT_REFUSED`` waits at most this long [s] for the controller's reason (sent before the
status that shows the stop; a lost one is sent again with the next statuses)."""

MOTION_STATES = frozenset({"homing", "tilting"})
"""The controller's states while a HOME or SET_TILT moves the table."""


class CommandAnswer(ABC):
    """The controller's answer to one command, as :class:`ChunkedStreamController` waits on it; for a motion
    (HOME, SET_TILT) answered in progress, its final answers are collected as they arrive until :meth:`close`."""

    in_progress: bool
    """Whether the controller answered "in progress": a motion that answers again when it ends."""

    over_from_ns: int
    """Controller time [ns] from which a status out of :data:`MOTION_STATES` shows the motion over."""

    @abstractmethod
    def shown(self, status: TableStatus) -> bool:
        """Whether ``status`` shows what the command did (it was taken, or received, after the answer)."""

    @abstractmethod
    def reached(self) -> bool | None:
        """Whether the motion's first final answer says it reached its target; None before a final answer."""

    @abstractmethod
    def shows_end(self, status: TableStatus) -> bool:
        """After a final answer: whether ``status`` shows where the motion ended."""

    @abstractmethod
    def close(self) -> None:
        """Stop collecting final answers (idempotent)."""


class LostBatches:
    """Batches missing from each source's sequence numbers (modulo 2³²): a gap counts the batches it skipped."""

    def __init__(self) -> None:
        self.count = 0
        self._expected: dict[int, int] = {}

    def receive(self, source: int, seq: int) -> None:
        expected = self._expected.get(source)
        if expected is not None and seq != expected:
            self.count += (seq - expected) % 2**32
        self._expected[source] = (seq + 1) % 2**32


class ChunkedStreamController(TableController):
    """A `TableController` whose commands are written once over :meth:`_request` and whose `stream` sends chunks
    ``lead`` ahead (module docstring)."""

    samples_per_chunk: int
    """Poses per setpoint chunk on this transport."""

    motion_stopped_result: str
    """The result named by the :class:`CommandFailedError` of a motion stopped before its target."""

    def __init__(self, url: str, table: TableModel | None = None, observe: bool = False) -> None:
        super().__init__(url)
        self.observe = observe
        """Connect without claiming the table (a monitor): its telemetry, STOP and EMERGENCY_STOP, no motion (the
        controller refuses a motion command while another host owns the table, and one from a monitor claims a
        table nobody owns)."""
        self.table = table or TableModel()
        """The table model a trajectory is checked against before it is streamed (``analysis.table.setpoints``):
        the controller's, the rig configuration's (default: Table IV and the default hexapod)."""
        self.feedback.mount(self.table.sensors)
        self.refusals: list[SetpointRefusal] = []
        """The setpoint chunks the controller refused for their values, each once, in the order they came."""
        self.clock = ClockSync()
        self._next_seq = 0
        self._claimed = False
        self._accel_lost = LostBatches()
        self._tilt_lost = LostBatches()

    refused: dict[str, int]
    """What the receive path dropped, by reason (``refused_bad_signature``: messages that did not verify, …)."""

    connect_timeout: float
    """How long :meth:`connect` waits for the controller [s]."""

    def _no_answer(self) -> NoReturn:
        """Why :meth:`connect` got no answer: another signing key (the controller's messages did not verify), or
        silence."""
        if self.refused["refused_bad_signature"]:
            raise TableError(f"{self.url}: the table controller answers, but {self.refused['refused_bad_signature']} "
                             "of its messages did not verify with this host's signing key: are host and controller "
                             "using the same signing key?")
        raise TableTimeoutError(f"{self.url}: no answer from the table controller within {self.connect_timeout} s")

    def _claim(self) -> None:
        """Claim the table for this host (the end of ``connect``): :class:`TableInUseError` naming the owner when
        another host owns it; nothing for a monitor (:attr:`observe`)."""
        if self.observe:
            return
        try:
            self._request("claim", (0.0, 0.0)).close()
        except CommandRejectedError:
            raise TableInUseError(f"{self.url}: table in use by {self._owner_refusal()}") from None
        self._claimed = True

    def _release(self) -> None:
        """Give the table up (the start of ``close``) if this host claimed it; not tried when no status came for
        the link timeout, and a RELEASE that is refused or gets no answer changes nothing here (the controller drops a
        silent owner's claim after its peer timeout)."""
        if not self._claimed:
            return
        self._claimed = False
        latest = self.feedback.latest
        if latest is None or time.monotonic_ns() - latest.host_ns > self.link_timeout * 1e9:
            return  # the controller is not answering (its link is lost): it drops a silent owner's claim itself
        with contextlib.suppress(CommandRefusedError, TableTimeoutError):
            self._request("release", (0.0, 0.0)).close()

    # ----- the backend's hooks

    @abstractmethod
    def _owner_refusal(self) -> str:
        """After a refused CLAIM: who owns the table and since when, as the controller said (``127.0.0.1:41234
        (system 255, component 190) since 2026-12-06 02:41:07 UTC, last heard 0.02 s ago``)."""

    @abstractmethod
    def _request(self, name: str, params: tuple[float, float]) -> CommandAnswer:
        """Send command ``name`` (``arm``, ``set_tilt`` …) with ``params`` until the controller answers; its answer,
        collecting final answers from before the command is sent (a quick final answer is not missed). Raises
        :class:`~drivers.controller.CommandDeniedError`, :class:`~drivers.controller.CommandRejectedError` or
        :class:`CommandFailedError` when the controller refused it, :class:`TableTimeoutError` without an answer
        after the retries."""

    @abstractmethod
    def _encode_chunk(self, seq: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray,
                      end_of_stream: bool) -> Any:
        """The transport's message for one chunk (controller times in ns)."""

    @abstractmethod
    def _send_chunk(self, message: Any) -> None:
        """Send one encoded chunk (signed where the transport signs)."""

    # ----- telemetry batches

    @property
    def accel_batches_lost(self) -> int:
        """Accelerometer batches missing from the sequence numbers received (each sensor's own)."""
        return self._accel_lost.count

    @property
    def tilt_batches_lost(self) -> int:
        """Body-tilt batches missing from the sequence numbers received (each body's own)."""
        return self._tilt_lost.count

    def _publish_accel(self, batch: AccelBatch) -> None:
        """Count a received accelerometer batch's gap, then publish it."""
        self._accel_lost.receive(batch.sensor_id, batch.seq)
        self.feedback.publish_accel(batch)

    def _publish_refusal(self, refusal: SetpointRefusal) -> None:
        """Keep a refusal the controller sent (each once: it sends it several times), and wake the waits."""
        if refusal not in self.refusals:
            self.refusals.append(refusal)
            self.feedback.notify()

    def _publish_tilt(self, batch: TiltBatch) -> None:
        """Count a received body-tilt batch's gap, then publish it."""
        self._tilt_lost.receive(batch.body_id, batch.seq)
        self.feedback.publish_tilt(batch)

    # ----- commands

    def arm(self) -> None:
        self._command("arm")

    def disarm(self) -> None:
        self._command("disarm")

    def home(self, *, wait: bool = True, timeout: float = 120.0) -> None:
        self._motion("home", (0.0, 0.0), wait, timeout)

    def set_tilt(self, angle: float, axis: str = "pitch", *, wait: bool = True, timeout: float = 120.0) -> None:
        if axis not in TILT_AXES:
            raise ValueError(f"axis must be one of {TILT_AXES}, got {axis!r}")
        if not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle!r}")
        self._motion("set_tilt", (angle, float(TILT_AXES.index(axis))), wait, timeout)

    def stop(self) -> None:
        self._command("stop")

    def emergency_stop(self) -> None:
        self._command("emergency_stop")

    def download_limits(self, levels: tuple[ControllerLevel, ...]) -> str | None:
        """SET_LIMIT (signed, MAVLink MAV_CMD_SHAKETABLE_SET_LIMIT or zenoh ``set_limit``): clear, then one command
        per level; a controller that refuses the first (UNSUPPORTED, FAILED: one without the levels) does not
        take them."""
        try:
            self._command("set_limit", (float(CLEAR_CODE), 0.0))
        except (CommandFailedError, CommandRejectedError) as exc:
            return f"the controller refused SET_LIMIT: {exc}"
        for level in levels:
            self._command("set_limit", level.params())
        return None

    def _command(self, name: str, params: tuple[float, float] = (0.0, 0.0)) -> CommandAnswer:
        """Send ``name`` (:meth:`_request`); unless it is in progress, return once a status shows what it did
        (:class:`TableTimeoutError` after :data:`~drivers.controller.STATUS_TIMEOUT` s: the link is lost). The
        answer, still collecting final answers when it is in progress."""
        answer = self._request(name, params)
        if not answer.in_progress:
            answer.close()
            self.wait_for_status(answer.shown, STATUS_TIMEOUT)
        return answer

    def _motion(self, name: str, params: tuple[float, float], wait: bool, timeout: float) -> None:
        """HOME or SET_TILT; with ``wait``, until it is over (module docstring): :class:`TableTimeoutError` after
        ``timeout`` s, :class:`CommandFailedError` when it was stopped before its target."""
        answer = self._command(name, params)
        if not answer.in_progress:
            return
        try:
            if not wait:
                return

            def over() -> bool:
                latest = self.feedback.latest
                return answer.reached() is not None or (latest is not None and latest.t_ns >= answer.over_from_ns
                                                        and latest.state not in MOTION_STATES)

            if not self.wait(over, timeout):
                raise TableTimeoutError(f"{name.upper()}: still moving after {timeout} s")
            if answer.reached() is not None:
                self.wait_for_status(answer.shows_end, STATUS_TIMEOUT)
            latest = self.status()
            reached = answer.reached()
            if not (latest.state == "armed" if reached is None else reached):
                raise CommandFailedError(name.upper(), self.motion_stopped_result, latest.state,
                                         "the motion was stopped before its target")
        finally:
            answer.close()

    # ----- streaming

    def stream(self, t: np.ndarray, poses: np.ndarray, *, lead: float = DEFAULT_LEAD,
               on_progress: Callable[[int, int], None] | None = None,
               on_start: Callable[[int], None] | None = None) -> StreamReport:
        spacing = sample_spacing(t, len(poses))
        if not (math.isfinite(lead) and lead > 0):
            raise ValueError(f"lead must be > 0 s, got {lead!r}")
        poses = playable_poses(self.url, self.table, poses, spacing, (self.status().pose, lead))
        spacing_ns = round(spacing * 1e9)
        lead_ns = round(lead * 1e9)
        per_chunk = self.samples_per_chunk
        capacity = self.status().buffer_capacity
        ahead = math.ceil(lead_ns / spacing_ns) + 2 * per_chunk  # the lead's samples and the chunks sent twice
        if capacity and ahead > capacity:
            raise ValueError(f"lead {lead:g} s: {ahead} setpoint samples would be buffered ahead, but the "
                             f"controller's buffer holds {capacity} (at {1e9 / spacing_ns:g} Hz): lower "
                             "[controller] lead_s or raise the controller's buffer_s")
        self.heap.hold()  # refreeze: what the runs before made is not visited by the stream's collections
        underruns_before = self.status().underruns
        refusals_before = len(self.refusals)
        first_seq = self._next_seq
        self._command("start_stream", (float(first_seq), 0.0))
        count = math.ceil(len(poses) / per_chunk)
        self._next_seq = (first_seq + count) % FIRST_SEQ_LIMIT
        reported = self.status().t_ns  # the START_STREAM's status (virtual time: where the clock holds)
        t_start = min(max(self.clock.to_controller(time.monotonic_ns()), reported), reported + AHEAD_NS) + lead_ns
        t_end = t_start + (len(poses) - 1) * spacing_ns
        lateness = np.zeros(count, dtype=np.int64)
        if on_start is not None:
            on_start(t_start)

        def report(sent: int, final: TableStatus | None) -> StreamReport:
            underruns = (final or self.status()).underruns - underruns_before
            return StreamReport(sent, min(sent * per_chunk, len(poses)), underruns, t_start, t_end, lead,
                                lateness[:sent], final)

        next_progress = time.monotonic_ns()
        previous = None
        for k in range(count):  # each chunk made just before it is due: no burst of work at the start
            first = k * per_chunk
            chunk_start = t_start + first * spacing_ns
            message = self._encode_chunk((first_seq + k) % FIRST_SEQ_LIMIT, chunk_start, spacing_ns,
                                         poses[first:first + per_chunk], k == count - 1)
            lateness[k] = self._wait_to_send(chunk_start - lead_ns, chunk_start - lead_ns - AHEAD_NS, previous,
                                             (first_seq + k - 1) % FIRST_SEQ_LIMIT)
            self.check_link()
            latest = self.feedback.latest
            if latest is not None and (latest.state in STOPPED_STATES or _left_stream(latest, t_start)):
                raise StreamAbortedError(self._stopped(latest, "", refusals_before), report(k, latest))
            self._send_chunk(message)
            if previous is not None:
                self._send_chunk(previous)
            previous = message
            if on_progress is not None and time.monotonic_ns() >= next_progress:
                on_progress(min(first + per_chunk, len(poses)), len(poses))
                next_progress += 100_000_000
        last_seq = (first_seq + count - 1) % FIRST_SEQ_LIMIT
        if previous is not None:
            self._send_chunk(previous)
            self._until_end_taken(previous, last_seq, t_start)
        remaining = max(0.0, (self.clock.to_host(t_end) - time.monotonic_ns()) * 1e-9)
        final = self.wait_for_status(
            lambda s: s.state in STOPPED_STATES or _left_stream(s, t_start), remaining + 2.0)
        if on_progress is not None:
            on_progress(len(poses), len(poses))
        if final.state != "armed" or final.last_chunk_seq != last_seq:  # stopped (and home) before its end
            raise StreamAbortedError(self._stopped(final, f", last chunk taken {final.last_chunk_seq} of "
                                                          f"{first_seq}…{last_seq}", refusals_before),
                                     report(count, final))
        return report(count, final)

    def _stopped(self, status: TableStatus, detail: str, refusals_before: int) -> str:
        """Why the table stopped the stream, as its :class:`StreamAbortedError` says: ``status``'s state and faults,
        ``detail``, and when it refused a chunk (``SETPOINT_REFUSED``) the reason it gave (refusals after the first
        ``refusals_before`` are this stream's; waited for at most :data:`REFUSAL_WAIT`)."""
        message = f"the table stopped the stream ({status.state}, faults {', '.join(status.faults) or 'none'}{detail})"
        if "SETPOINT_REFUSED" not in status.faults:
            return message
        if not self.wait(lambda: len(self.refusals) > refusals_before, REFUSAL_WAIT):
            return f"{message}: it refused a setpoint chunk (its reason did not arrive)"
        return f"{message}: it refused {self.refusals[refusals_before].reason}"

    def _until_end_taken(self, message: Any, last_seq: int, t_start: int) -> None:
        """Wait until a status shows the END_OF_STREAM chunk ``message`` (number ``last_seq``) taken or the table out
        of the stream that began at ``t_start`` [ns], sending it again meanwhile (module docstring);
        :class:`~drivers.controller.TableLinkLostError` if the link is lost."""

        def over() -> bool:
            latest = self.feedback.latest
            return latest is not None and (latest.last_chunk_seq == last_seq or latest.state in STOPPED_STATES
                                           or _left_stream(latest, t_start))

        while not self.wait(over, RESEND_S):
            self._resend_untaken(message, last_seq)

    def _resend_untaken(self, sent: Any, sent_seq: int) -> None:
        """Send the chunk sent last (``sent``, number ``sent_seq``; None before a stream's first) again unless the
        latest status shows it taken."""
        latest = self.feedback.latest
        if sent is not None and latest is not None and latest.last_chunk_seq != sent_seq:
            self._send_chunk(sent)

    def _wait_to_send(self, due: int, seen_after: int, sent: Any, sent_seq: int) -> int:
        """Wait until controller time ``due`` [ns] (module docstring: by the clock estimate or a status showing
        it, once a status shows ``seen_after`` [ns] or later), sending the chunk sent last (``sent``, number
        ``sent_seq``; None before the first) again every :data:`RESEND_S` while no status shows it taken; how late
        [ns, host time, ≥ 0] against the clock estimate's deadline."""
        deadline = self.clock.to_host(due)
        feedback = self.feedback

        def ready() -> bool:
            if not _shown(feedback.latest, seen_after):
                return False
            return _shown(feedback.latest, due) or time.monotonic_ns() >= deadline

        while not ready():  # a silent controller: the waits' link check raises TableLinkLostError
            if self.wait(ready, RESEND_S):
                break
            self._resend_untaken(sent, sent_seq)
        return max(time.monotonic_ns() - deadline, 0)


def _shown(status: TableStatus | None, t_ns: int) -> bool:
    """Whether ``status`` was taken at controller time ``t_ns`` [ns] or later."""
    return status is not None and status.t_ns >= t_ns


def _left_stream(status: TableStatus, t_start: int) -> bool:
    """Whether ``status`` shows the controller out of the stream that began at ``t_start`` [ns, controller time]:
    armed again after the first sample was due (a stop while at rest passes through ``stopping`` and its return
    home within one status period)."""
    return status.state == "armed" and status.t_ns >= t_start
