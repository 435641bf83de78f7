"""What the network's thread receives, matched to the SYNC it answered: the drives' TPDO1 (statusword, position),
the accelerometers' samples (published in batches of :data:`ACCEL_BATCH`) and the detector's overturn events; and
the statuses made of the SYNCs all six drives answered (:data:`STATUS_RATE` per second of measured time, and one
at every state change)."""

from __future__ import annotations

import time

import numpy as np

from drivers.canopen.faults import FAULT_ORDER
from drivers.canopen.master import MasterBase
from drivers.canopen.nodes import DriveLink, SensorLink
from drivers.controller import AccelBatch, Detection, TableStatus
from protocols.canopen.sensors import EVENT_TPDO1, ForceSample, decode_force, event_age_ns, event_tilt

STATUS_RATE = 50.0
"""Statuses per second (and one at every state change)."""

ACCEL_BATCH = 25
"""Accelerometer samples per published batch."""


class FeedbackFrames(MasterBase):
    """The PDO callbacks of the network's thread, and the poses and statuses of the frames they collect."""

    def _answered(self, timestamp: float, counter: int | None) -> int | None:
        """The index of the SYNC a frame with this time stamp answered: the last one sent before it — with
        ``counter`` (the SYNC counter the frame names), the last such one that carried it."""
        with self._lock:
            for wall, index, _ in reversed(self._syncs):
                if wall <= timestamp and (counter is None or self._sync_counter(index) == counter):
                    return index
        return None

    def _on_drive(self, link: DriveLink, data: bytes, stamp: float) -> None:
        """A drive's TPDO1 ``data`` received with time stamp ``stamp`` [s, the bus's clock]."""
        self._heard(stamp)
        feedback = self.drive_tpdo.decode(data)
        index = self._answered(stamp, feedback[2] if self.sync_counter else None)
        if index is None:
            return
        with self._lock:
            if index > link.answered:  # a later SYNC's answer already told its newer state
                link.statusword, link.position, link.answered = feedback.statusword, feedback.position_actual, index
            if index > self._framed:  # else its SYNC's status is out: it came too late for it
                self._frames.setdefault(index, {})[self._drives.index(link)] = feedback.position_actual

    def _on_accel(self, sensor: SensorLink, data: bytes, stamp: float) -> None:
        self._heard(stamp)
        sample = self.accel_tpdo.decode(data)
        index = self._answered(stamp, sample[3] if self.sync_counter else None)
        if index is None:
            return
        if sensor.next_index is not None and index < sensor.next_index:  # its SYNC's sample came (or was lost) before
            sensor.stale += 1
            return
        force = decode_force(ForceSample(*sample[:3]))
        if sensor.next_index is not None and index != sensor.next_index:
            self._publish_accel(sensor)
            sensor.lost += max(0, index - sensor.next_index)
            sensor.seq += 1  # a gap in the batches' sequence numbers marks the lost samples
        sensor.pending.append((index, force))
        sensor.next_index = index + 1
        if len(sensor.pending) >= ACCEL_BATCH:
            self._publish_accel(sensor)

    def _publish_accel(self, sensor: SensorLink) -> None:
        if not sensor.pending:
            return
        deadline = self._deadline(sensor.pending[0][0])
        if deadline is not None:
            self.feedback.publish_accel(AccelBatch(sensor.sensor_id, sensor.seq, deadline - self.sample_delay_ns,
                                                   self.period_ns, np.array([f for _, f in sensor.pending])))
            sensor.seq += 1
        else:
            sensor.lost += len(sensor.pending)
        sensor.pending.clear()

    def _on_event(self, data: bytes, stamp: float) -> None:
        self._heard(stamp)
        record = EVENT_TPDO1.decode(data)
        received = self.clock.now_ns() - round((time.time() - stamp) * 1e9)
        self.feedback.publish_detection(Detection(record.event_id, record.body_id, record.direction,
                                                  event_tilt(record), received - event_age_ns(record)))

    def _frame_pose(self, frame: dict[int, int]) -> np.ndarray:
        """The pose (6,) of the leg positions [drive units] one SYNC's TPDOs reported (forward kinematics)."""
        lengths = np.array([link.scaling.length(frame[leg]) for leg, link in enumerate(self._drives)])
        return self.table.pose_from_leg_lengths(lengths, guess=self._measured)

    def _measured_pose(self) -> np.ndarray:
        lengths = np.array([link.scaling.length(link.position) for link in self._drives])
        self._measured = self.table.pose_from_leg_lengths(lengths, guess=self._measured)
        return self._measured.copy()

    def _statuses(self, now: int, every: int) -> list[TableStatus]:
        """A status for every ``every``-th SYNC all six drives answered since the last call, in order — 50 Hz of
        measured time, whenever the answers arrive — and for the newest one when the state changed since the last
        status."""
        complete = sorted(index for index, frame in self._frames.items() if len(frame) == len(self._drives))
        if not complete:
            return []
        due = [index for index in complete if index % every == 0]
        if self._status_owed and complete[-1] not in due:
            due.append(complete[-1])
        statuses = [self._status(index, deadline, now) for index in due
                    if (deadline := self._deadline(index)) is not None]
        for old in [i for i in self._frames if i <= complete[-1]]:
            del self._frames[old]
        for old in [i for i in self._demands if i <= complete[-1]]:
            del self._demands[old]
        self._framed = complete[-1]
        self._status_owed = False
        return statuses

    def _status(self, index: int, deadline: int, now: int) -> TableStatus:
        """The status of SYNC ``index`` (at ``deadline``): the pose its TPDOs report, the state now."""
        self._measured = self._frame_pose(self._frames[index])
        depth = 0
        if self._state == "streaming" and self._trajectory is not None:
            depth = len(self._trajectory.poses) - self._trajectory.due(self._tau)
        self._published_state = self._state
        faults = tuple(name for name in FAULT_ORDER if name in self._faults)
        return TableStatus(deadline - self.feedback_delay_ns, self._state, depth, self._cycle_index % 2**32,
                           self._underruns, faults, 0, self._measured.copy(), now,
                           following_error=self._following_error(index))

    def _following_error(self, index: int) -> np.ndarray | None:
        """Each leg's following error at SYNC ``index`` [m]: the target due then (the position demand, as a CSP
        drive's 0x60F4 counts it, which TPDO1 has no room for: ``protocols.canopen.pdo_maps``) minus the position
        its TPDO reported; None without a target following a reference for it (the drives holding their own)."""
        demand = self._demands.get(index)
        if demand is None:
            return None
        frame = self._frames[index]
        return np.array([link.scaling.length(demand[leg]) - link.scaling.length(frame[leg])
                         for leg, link in enumerate(self._drives)])
