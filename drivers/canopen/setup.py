"""Setting up the CANopen network (package docstring, *Connecting*): NMT pre-operational, the SDO configuration
and PDO maps of every node, NMT operational and the wait until every node's heartbeat reports it; closing."""

from __future__ import annotations

import threading
import time
from typing import Any

import can
import canopen

from drivers.canopen.master import MasterBase
from drivers.canopen.nodes import NMT_OPERATIONAL, DriveLink, NodeLink, SensorLink
from drivers.controller import TableError, TableTimeoutError
from protocols.canopen import (
    LEG_NODE_IDS,
    MASTER_NODE_ID,
    RPDO1,
    configure,
    heartbeat_consumer_entry,
    velocity_increments,
)
from protocols.canopen import od as drive_od
from protocols.canopen.receive_buffer import widen_receive_buffer
from protocols.canopen.sensors import (
    ACCELEROMETER_NODE_IDS,
    DETECTOR_NODE_ID,
    EVENT_TPDO1,
    SAMPLE_DELAY,
    load_accelerometer_od,
    load_detector_od,
)

HEARTBEAT_PERIOD = 0.05
"""Heartbeat period of every node [s] (0x1017 in ms)."""

CONSUMER_TIME = 0.1
"""The drives' consumer time of the master's heartbeat [s] (0x1016): without one for this long they stop the table."""

SDO_TIMEOUT = 1.0
"""How long [s] an SDO request waits for its answer (once; the configuration at connect is the only SDO traffic)."""


class SetUp(MasterBase):
    """Connects and closes the master: the nodes' set-up, their PDO and EMCY callbacks
    (:mod:`~drivers.canopen.feedback`, :mod:`~drivers.canopen.faults`), then the cycle thread
    (:mod:`~drivers.canopen.cycle`)."""

    def connect(self) -> None:
        if self._network is not None:
            return
        self.heap.hold()
        bus = can.Bus(interface=self.interface, channel=self.channel, bitrate=self.bitrate)
        self.receive_buffer_bytes = widen_receive_buffer(bus)
        network = canopen.Network(bus)
        network.NOTIFIER_CYCLE = 0.05  # disconnect() waits up to one cycle
        self._network = network
        try:
            network.connect()
            self._drives = [DriveLink(network.add_node(leg, drive_od.load_od(leg))) for leg in LEG_NODE_IDS]
            self._sensors = [SensorLink(network.add_node(node_id, load_accelerometer_od(node_id)), k)
                             for k, node_id in enumerate(ACCELEROMETER_NODE_IDS[:self.accelerometer_count])]
            self._detector = NodeLink(network.add_node(DETECTOR_NODE_ID, load_detector_od())) if self.detector else None
            network.nmt.state = "PRE-OPERATIONAL"
            self._configure()
            started = time.monotonic_ns()
            network.nmt.state = "OPERATIONAL"
            for link in self._links():
                link.started_ns = started
            self._closing.clear()
            self._thread = threading.Thread(target=self._run, name="canopen-cycle", daemon=True)
            self._thread.start()
            self._wait_operational(time.monotonic() + self.connect_timeout)
            self._check_alive()
        except BaseException:
            self.close()
            raise

    def _wait_operational(self, deadline: float) -> None:
        """Until every node's heartbeat reports NMT operational and the first status is out (at most until
        ``deadline`` [s, monotonic]). A node whose heartbeat, sent after the last start command, reports another
        state (it missed the command, or booted again) is started once more."""
        def ready() -> bool:
            return self._failure is not None or (self.feedback.latest is not None and not self._behind())

        while not self.feedback.wait_for(ready, HEARTBEAT_PERIOD):
            if time.monotonic() > deadline:
                raise TableTimeoutError(f"{self.url}: not every node reported operational in its heartbeat within "
                                        f"{self.connect_timeout} s ({self._nmt_states()})")
            for link in self._behind():
                if link.heartbeat_ns is not None and link.heartbeat_ns > link.started_ns:
                    link.started_ns = time.monotonic_ns()
                    link.node.nmt.state = "OPERATIONAL"

    def _behind(self) -> list[NodeLink]:
        """The nodes whose last heartbeat did not report NMT operational."""
        return [link for link in self._links() if link.nmt_state != NMT_OPERATIONAL]

    def nmt_states(self) -> dict[int, str]:
        """Each node's NMT state as its last heartbeat reported it (node id → name; "silent" before one)."""
        return {link.node.id: "silent" if link.nmt_state is None
                else canopen.nmt.NMT_STATES.get(link.nmt_state, hex(link.nmt_state)).lower()
                for link in self._links()}

    def _nmt_states(self) -> str:
        return ", ".join(f"node {node} {state}" for node, state in self.nmt_states().items())

    def _configure(self) -> None:
        """SDO configuration of every node (package docstring)."""
        heartbeat_ms = round(HEARTBEAT_PERIOD * 1000)
        consumer = heartbeat_consumer_entry(MASTER_NODE_ID, round(CONSUMER_TIME * 1000))
        geometry = self.table.geometry
        deadline = time.monotonic() + self.connect_timeout
        delays = set()
        for link in self._drives:
            node = link.node
            sdo = self._sdo(node, deadline)
            if sdo[drive_od.DEVICE_TYPE].raw != drive_od.DEVICE_TYPE_CIA402_SERVO or not (
                    sdo[drive_od.SUPPORTED_DRIVE_MODES].raw & drive_od.SUPPORTED_MODE_CSP):
                raise TableError(f"{self.url}: node {node.id} is not a CiA 402 servo drive with CSP")
            sdo[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            sdo[drive_od.CONSUMER_HEARTBEAT_TIME][1].raw = consumer
            sdo[drive_od.SYNC_COUNTER_OVERFLOW].raw = self.sync_counter
            sdo[drive_od.COMMUNICATION_CYCLE_PERIOD].raw = self.period_ns // 1000
            low, high = self.scaling.software_position_limits
            sdo[drive_od.SOFTWARE_POSITION_LIMIT][1].raw = low
            sdo[drive_od.SOFTWARE_POSITION_LIMIT][2].raw = high
            sdo[drive_od.MAX_PROFILE_VELOCITY].raw = velocity_increments(geometry.leg_speed)
            sdo[drive_od.FOLLOWING_ERROR_WINDOW].raw = self.following_error_window_um
            sdo[drive_od.MODES_OF_OPERATION].raw = drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION
            if sdo[drive_od.MODES_OF_OPERATION_DISPLAY].raw != drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION:
                raise TableError(f"{self.url}: drive {node.id} did not take cyclic synchronous position mode")
            for pdo_map, spec in ((node.rpdo[1], RPDO1), (node.tpdo[1], self.drive_tpdo)):
                configure(pdo_map, spec, node.id)
                pdo_map.save()
            delays.add((sdo[drive_od.TARGET_DELAY].raw, sdo[drive_od.FEEDBACK_DELAY].raw))
            node.tpdo[1].add_callback(lambda pdo_map, link=link: self._on_drive(link, pdo_map))
            node.emcy.add_callback(lambda error, link=link: self._on_emcy(link, error))
        if len(delays) != 1:
            raise TableError(f"{self.url}: the drives declare different target/feedback delays {sorted(delays)} µs")
        (target_us, feedback_us), = delays
        self.target_delay_ns, self.feedback_delay_ns = target_us * 1000, feedback_us * 1000
        sample_delays = set()
        for sensor in self._sensors:
            sdo = self._sdo(sensor.node, deadline)
            sdo[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            sdo[drive_od.SYNC_COUNTER_OVERFLOW].raw = self.sync_counter
            configure(sensor.node.tpdo[1], self.accel_tpdo, sensor.node.id)
            sensor.node.tpdo[1].save()
            sample_delays.add(sdo[SAMPLE_DELAY].raw)
            sensor.node.tpdo[1].add_callback(lambda pdo_map, sensor=sensor: self._on_accel(sensor, pdo_map))
        if len(sample_delays) > 1:
            raise TableError(f"{self.url}: the accelerometers declare different sample delays {sorted(sample_delays)}")
        self.sample_delay_ns = sample_delays.pop() * 1000 if sample_delays else 0
        if self._detector is not None:
            node = self._detector.node
            self._sdo(node, deadline)[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            configure(node.tpdo[1], EVENT_TPDO1, node.id)
            node.tpdo[1].save()
            node.tpdo[1].add_callback(self._on_event)

    def _sdo(self, node: canopen.RemoteNode, deadline: float) -> Any:
        """The node's SDO client once the node answers (asked until ``deadline`` [s, monotonic]: a node may still
        be booting), with :data:`SDO_TIMEOUT` per request."""
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
        while True:
            try:
                node.sdo[drive_od.DEVICE_TYPE].raw  # noqa: B018 - the read is the question
                return node.sdo
            except canopen.SdoCommunicationError:
                if time.monotonic() > deadline:
                    raise TableTimeoutError(f"{self.url}: node {node.id} does not answer SDO (is it on the bus?)") \
                        from None

    def close(self) -> None:
        if self._network is None:
            return
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self._network.disconnect()
        self._network = None
        self.feedback.close()
        self.heap.release()
