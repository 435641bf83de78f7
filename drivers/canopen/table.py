""":class:`CanopenTable`, the table's CANopen master: its set-up, SYNC cycle, fault supervision, feedback and
motions (:mod:`drivers.canopen.master`) in one `TableController`."""

from __future__ import annotations

import math
from typing import Any

import canopen

from drivers.bodies import TableBody
from drivers.canopen.cycle import SyncCycle
from drivers.canopen.faults import FaultSupervision
from drivers.canopen.feedback import FeedbackFrames
from drivers.canopen.motion import Motions
from drivers.canopen.setup import SetUp
from drivers.controller import TableError
from protocols.canopen.sensors import BODY_COUNT, BODY_RECORDS, MAX_BODIES


class CanopenTable(SetUp, SyncCycle, FaultSupervision, FeedbackFrames, Motions):
    """The table's CANopen master on ``canopen://CHANNEL?interface=NAME`` (package docstring).

    Options (keywords, or the URL's query): ``interface``, ``bitrate`` [bit/s], ``rate`` [Hz] of SYNC,
    ``accelerometers`` (nodes 0x21…); ``detector`` whether the overturn detector (node 0x30) is on the bus;
    ``table`` the table model (limits, geometry); ``connect_timeout`` and ``command_timeout`` [s] (ARM and DISARM
    wait for the drives' states); ``consumer_time`` [s] of the nodes' heartbeats
    (:data:`~drivers.canopen.master.NODE_CONSUMER_TIME`); ``clock`` what paces the SYNC cycle
    (:mod:`drivers.canopen.clock`: the host's monotonic clock unless given; a stepped one for drives emulated in this
    process). Raises :class:`~protocols.canopen.BusLoadError` when the
    rate does not fit.
    """

    def check_link(self) -> None:
        """Nothing to check by the statuses' age: this master *is* the controller and makes its statuses from the
        drives' answers, which stop while they are braked or faulted; a drive that falls silent, or a bus from which
        nothing is heard for :attr:`link_timeout`, is caught by the master's own heartbeat consumers (a DRIVE fault,
        ``silent_drives``), the master's thread failing by :meth:`wait_for_status`'s timeouts."""

    def bodies(self, timeout: float = 3.0) -> tuple[TableBody, ...] | None:
        """The bodies the overturn detector holds (:mod:`protocols.canopen.sensors`: 0x2201 and the body records
        from 0x2210), read by SDO, each request waiting at most ``timeout`` [s]; None without a detector on the bus,
        or from one that does not answer or whose object dictionary holds no bodies (an SDO abort)."""
        if self._network is None:
            raise TableError(f"{self.url}: not connected")
        if self._detector is None:
            return None
        sdo = self._detector.node.sdo
        configured, sdo.RESPONSE_TIMEOUT = sdo.RESPONSE_TIMEOUT, timeout
        try:
            count = sdo[BODY_COUNT].raw
            if not 0 <= count <= MAX_BODIES:
                raise TableError(f"{self.url}: the overturn detector reports {count} bodies (0x{BODY_COUNT:04X}); "
                                 f"its object dictionary holds at most {MAX_BODIES}")
            bodies = []
            for k in range(count):
                record = sdo[BODY_RECORDS + k]
                values = [float(record[sub].raw) for sub in range(1, 6)]
                if not all(math.isfinite(v) and abs(v) < 100.0 for v in values):  # a plate is metres, not hectometres
                    raise TableError(f"{self.url}: body {k} of the overturn detector (0x{BODY_RECORDS + k:04X}) is "
                                     f"not a size and place in metres: {values}")
                bodies.append(TableBody(k, *values))
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError):
            return None
        finally:
            sdo.RESPONSE_TIMEOUT = configured
        return tuple(bodies)

    def link_stats(self) -> dict[str, Any]:
        """Bus load, rate, cycle lateness, accelerometer samples lost and stale (their SYNC's sample was had or
        counted lost already: dropped), the SYNC counter's overflow value (0: off), the receive buffer [bytes],
        duplicate overturn events dropped, each node's heartbeat age [s] and NMT state, and the EMCY codes received
        per node."""
        now = self.clock.now_ns()
        links = self._links()
        return {"rate_hz": self.rate, "bitrate": self.bitrate, "bus_load": self.bus_load,
                "target_delay_s": self.target_delay_ns * 1e-9, "feedback_delay_s": self.feedback_delay_ns * 1e-9,
                "late_cycles": self.late_cycles, "lateness_max_s": self.lateness_max_ns * 1e-9,
                "accel_samples_lost": sum(s.lost for s in self._sensors),
                "accel_samples_stale": sum(s.stale for s in self._sensors),
                "sync_counter": self.sync_counter, "receive_buffer_bytes": self.receive_buffer_bytes,
                "duplicate_detections": self.feedback.duplicate_detections,
                "heartbeat_age_s": {link.node.id: link.heartbeat_age(now) for link in links},
                "nmt_state": self.nmt_states(),
                "emcy": {link.node.id: [code for code, _ in link.emcy] for link in links if link.emcy},
                "silent_drives": sorted(self.silent_drives)}
