"""Fault supervision (package docstring, *faults*): EMCYs, the drives' heartbeats and statuswords latch faults, and
a stopping fault quick-stops every drive; the state changes that the drives' states and the clock decide (armed
once all six are enabled, faulted once a stopping fault's reaction is over, a move or a stream ended)."""

from __future__ import annotations

import canopen

from analysis.table.moves import Move
from drivers.canopen.master import DRIVING_STATES, MasterBase
from drivers.canopen.nodes import DriveLink, NodeLink
from drivers.controller import FaultSource
from protocols.canopen import State, StatusBit
from protocols.canopen import od as drive_od

FAULT_ORDER = ("DRIVE", "STROKE", "STREAM_SILENT", "HEARTBEAT_LOST", "UNSIGNED_COMMAND", "SETPOINT_LIMIT",
               "CHUNK_GAP", "UNDERRUN", "SETPOINT_REFUSED")
"""Fault names in the order of their bits (``docs/table-controller.md``; the same as MAVLink's)."""

_STOPPING_FAULTS = frozenset({"DRIVE", "HEARTBEAT_LOST", "STREAM_SILENT", "SETPOINT_REFUSED"})
_EMCY_FAULTS = {drive_od.EMCY_HEARTBEAT_ERROR: "HEARTBEAT_LOST", drive_od.EMCY_SYNC_LOST: "STREAM_SILENT",
                drive_od.EMCY_REFERENCE_LIMIT: "SETPOINT_REFUSED"}
"""EMCY codes that name their fault; every other code (except error reset, 0x00xx) is a DRIVE fault."""
_FAULTY = frozenset({State.FAULT, State.FAULT_REACTION_ACTIVE})


class FaultSupervision(MasterBase):
    """Latches faults and moves the master's state on what the drives report."""

    def _on_emcy(self, link: DriveLink, error: canopen.emcy.EmcyError) -> None:
        if error.code & 0xFF00 == 0:
            return  # error reset
        with self._lock:
            link.emcy.append((error.code, self.clock.now_ns()))
            self._sources.append(FaultSource(link.node_id, error.code))
            self._fault(_EMCY_FAULTS.get(error.code, "DRIVE"))

    def silent(self, link: NodeLink, now: int) -> bool:
        """Whether ``link``'s node has fallen silent at ``now`` [ns, the master's clock]: no heartbeat yet; or none for
        :attr:`consumer_time` on the bus's clock (PDOs that reached the bus that long after its last heartbeat
        were handled: the master is not merely behind in reading the bus); or nothing at all handled from the bus
        for :attr:`~drivers.controller.TableController.link_timeout` (the rig TOML's ``link_timeout_s``: the whole
        bus silent, or this host unable to read it). A master held up — its process unscheduled on a busy host, its
        receive thread waiting for the interpreter — finds the heartbeats sent meanwhile in the socket and judges
        them by their time stamps, as the emulated drives judge this master's (:mod:`sim_table.canopen_endpoint`)."""
        if link.heartbeat_ns is None:
            return True
        if (now - link.heartbeat_ns) * 1e-9 <= self.consumer_time:
            return False
        return (self._heard_stamp - link.heartbeat_stamp > self.consumer_time
                or (now - max(self._heard_ns, link.heartbeat_ns)) * 1e-9 > self.link_timeout)

    def _supervise(self, now: int, deadline: int) -> None:
        """Faults from heartbeats and statuswords; the state changes the drives' states and the clock decide."""
        for leg, link in enumerate(self._drives, start=1):
            if link.heartbeat_ns is not None and self.silent(link, now):
                self.silent_drives.add(leg)
                self._fault("DRIVE")
            if self._state in DRIVING_STATES and link.state in _FAULTY and not link.node.emcy.active:
                self._fault("DRIVE")  # in fault without an EMCY (lost, or sent before this master listened)
            if link.statusword is not None and link.statusword & StatusBit.INTERNAL_LIMIT_ACTIVE:
                self._faults.add("SETPOINT_LIMIT")
        states = [link.state for link in self._drives]
        enabled = [s is State.OPERATION_ENABLED for s in states]
        if self._arming and all(enabled):
            self._arming = False
            self._pose = self._measured_pose()
            self._velocity[:] = 0.0
            self._set_state("armed")
        elif self._state == "stopping" and self._stop_reason is not None and not any(
                e or s is State.FAULT_REACTION_ACTIVE for e, s in zip(enabled, states, strict=True)):
            self._set_state("faulted")
        elif self._state in ("homing", "tilting") and self._move is not None and self._arrived(self._move, deadline):
            self._move = None
            self._set_state("armed")
        elif self._state == "streaming" and self._trajectory is not None and deadline >= self._trajectory.t_end_ns:
            self._played, self._trajectory = self._trajectory, None
            self._set_state("armed")
        elif (self._state == "stopping" and self._stop_reason is None and self._homing_after_stop
              and self._move is not None and self._arrived(self._move, deadline)):
            self._move = None
            self._set_state("armed")

    def _arrived(self, move: Move, deadline: int) -> bool:
        """Whether ``move`` has ended: its reference arrived and the newest measured pose is in position (a DRIVE
        fault, which stops the table, when that is overdue by the newest SYNC all six drives answered: a master
        behind in reading their answers is not a leg that failed to follow)."""
        if deadline < move.end_ns:
            return False
        complete = [index for index, frame in self._frames.items() if len(frame) == len(self._drives)]
        if complete and move.in_position(self._frame_pose(self._frames[max(complete)])):
            deadline_in_position = self._deadline(max(complete))
            if deadline_in_position is not None:
                self._arrived_ns = deadline_in_position - self.feedback_delay_ns
            return True
        answered = self._deadline(max(complete) if complete else self._framed)
        if answered is not None and move.settle_overdue(answered):
            self._fault("DRIVE")  # a following error: the legs did not reach their targets
        return False

    def _fault(self, name: str) -> None:
        """Latch a fault; a stopping one quick-stops every drive (package docstring)."""
        self._faults.add(name)
        if name in _STOPPING_FAULTS and (self._state in DRIVING_STATES or self._state == "stopping" or self._arming):
            self._arming = False
            self._stop_reason = self._stop_reason or name
            self._move = self._trajectory = None
            self._set_state("stopping")
