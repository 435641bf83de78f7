"""The SYNC cycle (package docstring, *The cycle*): one thread, sleeping to absolute deadlines ``t_n = t_0 + n·T``,
that supervises the drives, writes each RPDO1 (controlword, target [the drive's units]) for the reference at
``t_n + D``, sends SYNC and every :data:`MASTER_HEARTBEAT_PERIOD` the master's heartbeat, and publishes the statuses;
it counts late cycles and underruns."""

from __future__ import annotations

import time

import numpy as np

from drivers.canopen.feedback import STATUS_RATE
from drivers.canopen.master import DRIVING_STATES, MasterBase
from drivers.canopen.nodes import NMT_OPERATIONAL, DriveLink
from drivers.controller import FaultSource, TableStatus
from protocols.canopen import MASTER_NODE_ID, RPDO1, Command, Setpoint, State, command_towards_operation, controlword

MASTER_HEARTBEAT_PERIOD = 0.02
"""The master's heartbeat period [s]: five within the drives' consumer time."""

SYNC_COB_ID = 0x80
"""COB-ID of SYNC."""

_HEARTBEAT_COB_ID = 0x700


class SyncCycle(MasterBase):
    """The cycle thread (:meth:`_run`) and what one cycle sends."""

    def _run(self) -> None:
        heartbeat_every = max(1, round(MASTER_HEARTBEAT_PERIOD * 1e9 / self.period_ns))
        status_every = max(1, round(1e9 / STATUS_RATE / self.period_ns))
        deadline = self.clock.now_ns() + self.period_ns
        index = 0
        try:
            while not self._closing.is_set():
                self._next_deadline = deadline
                lateness = self.clock.sleep_until(deadline)
                statuses, sources = self._cycle(index, deadline, lateness, index % heartbeat_every == 0,
                                                status_every)
                for status in statuses:
                    self.feedback.publish_status(status, sources)
                index += 1
                deadline += self.period_ns
        except BaseException as exc:  # the drives' heartbeat consumers notice the silence and stop the table
            self._failure = exc
            self.feedback.notify()

    def _cycle(self, index: int, deadline: int, lateness: int, heartbeat: bool,
               status_every: int) -> tuple[list[TableStatus], tuple[FaultSource, ...]]:
        """One cycle at ``deadline`` (package docstring); the statuses to publish and the EMCYs received before them
        (the sources of the faults they raise)."""
        assert self._network is not None
        now = self.clock.now_ns()
        with self._lock:
            self._cycle_index = index
            self._count_lateness(lateness)
            self._supervise(now, deadline)
            setpoints = self._setpoints(deadline + self.target_delay_ns)
            if self._driven:  # the targets follow a reference: the position demand of the SYNC they are due at
                self._demands[index + round(self.target_delay_ns / self.period_ns)] = [
                    setpoint.target_position for setpoint in setpoints]
            self._status_owed |= self._state != self._published_state  # until a SYNC all six answered shows it
        send = self._network.send_message
        for link, setpoint in zip(self._drives, setpoints, strict=True):
            send(RPDO1.cob_id(link.node_id), RPDO1.encode(setpoint))
        with self._lock:
            self._syncs.append((time.time(), index, deadline))
        send(SYNC_COB_ID, bytes([self._sync_counter(index)]) if self.sync_counter else b"")
        if heartbeat:
            send(_HEARTBEAT_COB_ID + MASTER_NODE_ID, bytes([NMT_OPERATIONAL]))
        with self._lock:
            statuses = self._statuses(now, status_every)
            sources = tuple(self._sources) if statuses else ()
            if statuses:
                self._sources.clear()
            return statuses, sources

    def _count_lateness(self, lateness: int) -> None:
        self.lateness_max_ns = max(self.lateness_max_ns, lateness)
        self.late_cycles += lateness >= self.period_ns
        if self._state != "streaming":
            return
        self._stream_cycles += 1
        if self._lateness is not None:
            self._lateness.append(lateness)
        if lateness > self.target_delay_ns - self.period_ns:  # the drives played their last target already
            if not self._dry:
                self._underruns += 1
                self._faults.add("UNDERRUN")
            self._dry = True
        else:
            self._dry = False

    def _setpoints(self, tau: int) -> list[Setpoint]:
        """Each drive's controlword and target for the SYNC whose targets are reached at ``tau``."""
        reference = self._reference(tau)
        targets = [link.position for link in self._drives]
        self._driven = reference is not None
        if reference is not None:
            targets = self._targets(reference)
        setpoints = []
        for link, target in zip(self._drives, targets, strict=True):
            word = controlword(self._drive_command(link))
            if word & link.word & 0x80:  # a fault reset acts on a rising bit 7: a word with it clear in between
                word = controlword(Command.DISABLE_VOLTAGE)
            link.word = word
            setpoints.append(Setpoint(word, target))
        return setpoints

    def _drive_command(self, link: DriveLink) -> Command:
        """What a drive is told in the current state."""
        if self._arming:
            return command_towards_operation(link.state or State.SWITCH_ON_DISABLED) or (
                Command.ENABLE_OPERATION if link.state is State.OPERATION_ENABLED else Command.DISABLE_VOLTAGE)
        if self._state in DRIVING_STATES or (self._state == "stopping" and self._stop_reason is None):
            return Command.ENABLE_OPERATION
        if self._state in ("stopping", "faulted", "emergency_stopped"):
            return Command.QUICK_STOP
        return Command.DISABLE_OPERATION  # idle

    def _targets(self, pose: np.ndarray) -> list[int]:
        """Target positions [drive units] of a pose: clipped to the envelope and the legs' stroke (latching the
        faults)."""
        clipped = np.clip(pose, -self._bounds, self._bounds)
        if not np.array_equal(clipped, pose):
            self._faults.add("SETPOINT_LIMIT")
        g = self.table.geometry
        wanted = self.table.leg_lengths(clipped)
        lengths = np.clip(wanted, g.leg_min, g.leg_max)
        if not np.array_equal(lengths, wanted):
            self._faults.add("STROKE")
        return [link.scaling.position(length, leg)
                for leg, (link, length) in enumerate(zip(self._drives, lengths.tolist(), strict=True), start=1)]
