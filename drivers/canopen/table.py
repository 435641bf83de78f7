""":class:`CanopenTable`, the table's CANopen master: its set-up, SYNC cycle, fault supervision, feedback and
motions (:mod:`drivers.canopen.master`) in one `TableController`."""

from __future__ import annotations

import time
from typing import Any

from drivers.canopen.cycle import SyncCycle
from drivers.canopen.faults import FaultSupervision
from drivers.canopen.feedback import FeedbackFrames
from drivers.canopen.motion import Motions
from drivers.canopen.setup import SetUp


class CanopenTable(SetUp, SyncCycle, FaultSupervision, FeedbackFrames, Motions):
    """The table's CANopen master on ``canopen://CHANNEL?interface=NAME`` (package docstring).

    Options (keywords, or the URL's query): ``interface``, ``bitrate`` [bit/s], ``rate`` [Hz] of SYNC,
    ``accelerometers`` (nodes 0x21…); ``detector`` whether the overturn detector (node 0x30) is on the bus;
    ``table`` the table model (limits, geometry); ``connect_timeout`` and ``command_timeout`` [s] (ARM and DISARM
    wait for the drives' states). Raises :class:`~protocols.canopen.BusLoadError` when the rate does not fit.
    """

    def check_link(self) -> None:
        """Nothing to check by the statuses' age: this master *is* the controller and makes its statuses from the
        drives' answers, which stop while they are braked or faulted; a drive, sensor or detector that falls silent
        is caught by the master's own heartbeat consumers (a DRIVE fault, ``silent_drives``), the master's thread
        failing by :meth:`wait_for_status`'s timeouts."""

    def link_stats(self) -> dict[str, Any]:
        """Bus load, rate, cycle lateness, accelerometer samples lost, duplicate overturn events dropped, each
        node's heartbeat age [s] and NMT state, and the EMCY codes received per node."""
        now = time.monotonic_ns()
        links = self._links()
        return {"rate_hz": self.rate, "bitrate": self.bitrate, "bus_load": self.bus_load,
                "target_delay_s": self.target_delay_ns * 1e-9, "feedback_delay_s": self.feedback_delay_ns * 1e-9,
                "late_cycles": self.late_cycles, "lateness_max_s": self.lateness_max_ns * 1e-9,
                "accel_samples_lost": sum(s.lost for s in self._sensors),
                "duplicate_detections": self.feedback.duplicate_detections,
                "heartbeat_age_s": {link.node.id: link.heartbeat_age(now) for link in links},
                "nmt_state": self.nmt_states(),
                "emcy": {link.node.id: [code for code, _ in link.emcy] for link in links if link.emcy},
                "silent_drives": sorted(self.silent_drives)}
