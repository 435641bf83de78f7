"""Setting up the CANopen network (package docstring, *Connecting*): NMT pre-operational, the SDO configuration
and PDO maps of every node, NMT operational and the wait until every node's heartbeat reports it; closing."""

from __future__ import annotations

import math
import threading
import time

import can
import canopen

from drivers.canopen.master import MasterBase
from drivers.canopen.nodes import NMT_OPERATIONAL, DriveLink, NodeLink, SensorLink
from drivers.canopen.sdo import I8, I32, U8, U16, U32, DriveSetupError, NodeSdo
from drivers.canopen.survey import DriveReport, eds_objects, inspect_drive, require_drivable
from drivers.canopen.units import leg_scaling
from drivers.controller import TableTimeoutError
from protocols.canopen import MASTER_NODE_ID, RPDO1, LegScaling, heartbeat_consumer_entry
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
from protocols.canopen.units import interpolation_period

HEARTBEAT_PERIOD = 0.05
"""Heartbeat period of every node [s] (0x1017 in ms)."""

CONSUMER_TIME = 0.1
"""The drives' consumer time of the master's heartbeat [s] (0x1016): without one for this long they stop the table."""

WINDOW_OFF = 0xFFFF_FFFF
"""0x6065 value that switches a drive's following-error supervision off (CiA 402)."""

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
            geometry = self.table.geometry
            self._drives = [DriveLink(network.add_node(node_id, canopen.ObjectDictionary()), self.clock,
                                      LegScaling(geometry.leg_min, geometry.leg_max)) for node_id in self.node_ids]
            self._sensors = [SensorLink(network.add_node(node_id, load_accelerometer_od(node_id)), self.clock, k)
                             for k, node_id in enumerate(ACCELEROMETER_NODE_IDS[:self.accelerometer_count])]
            self._detector = (NodeLink(network.add_node(DETECTOR_NODE_ID, load_detector_od()), self.clock)
                              if self.detector else None)
            network.nmt.state = "PRE-OPERATIONAL"
            self._configure()
            started = self.clock.now_ns()
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
                    link.started_ns = self.clock.now_ns()
                    link.node.nmt.state = "OPERATIONAL"

    def _behind(self) -> list[NodeLink]:
        """The nodes whose last heartbeat did not report NMT operational."""
        return [link for link in self._links() if link.nmt_state != NMT_OPERATIONAL]

    def nmt_states(self) -> dict[int, str]:
        """Each node's NMT state as its last heartbeat reported it (node id → name; "silent" before one)."""
        return {link.node_id: "silent" if link.nmt_state is None
                else canopen.nmt.NMT_STATES.get(link.nmt_state, hex(link.nmt_state)).lower()
                for link in self._links()}

    def _nmt_states(self) -> str:
        return ", ".join(f"node {node} {state}" for node, state in self.nmt_states().items())

    def _configure(self) -> None:
        """SDO configuration of every node (package docstring): first every drive is read and checked (nothing is
        written to any drive while one of them would be refused), then each is set up."""
        deadline = time.monotonic() + self.connect_timeout
        geometry = self.table.geometry
        sdos = []
        self.reports = []
        for leg, (link, settings) in enumerate(zip(self._drives, self.drive_settings.legs, strict=True), start=1):
            sdo = self._answering(NodeSdo(self.url, link.node, f"leg {leg} (node {link.node.id})", SDO_TIMEOUT),
                                  deadline)
            eds = eds_objects(settings.eds, link.node_id, settings.where or "[drives]") if settings.eds else None
            report = inspect_drive(sdo, leg, eds)
            require_drivable(report, self.url)
            link.scaling = leg_scaling(self.url, report, settings, geometry)
            if self.sync_counter and not (report.has(drive_od.SYNC_COUNTER_OVERFLOW)
                                          and report.profile and report.profile.answered_sync):
                raise DriveSetupError(f"{self.url}: leg {leg} (node {link.node.id}): counted SYNCs were asked for "
                                      "(sync_counter) but this drive cannot echo the SYNC counter (it needs 0x1019 "
                                      "and a profile with an answered-SYNC object): leave sync_counter off")
            self.reports.append(report)
            sdos.append(sdo)
        delays = {self._drive_delays(sdo, report) for sdo, report in zip(sdos, self.reports, strict=True)}
        if len(delays) != 1:
            raise DriveSetupError(f"{self.url}: the drives declare different target/feedback delays "
                                  f"{sorted(delays)} µs")
        (target_us, feedback_us), = delays
        self.target_delay_ns, self.feedback_delay_ns = target_us * 1000, feedback_us * 1000
        for link, sdo, report in zip(self._drives, sdos, self.reports, strict=True):
            self._configure_drive(link, sdo, report)
        self._configure_sensors(deadline)

    def survey(self) -> list[DriveReport]:
        """Read every leg drive without configuring or enabling anything (``rig table check``): NMT pre-operational,
        then what each is (:mod:`drivers.canopen.survey`) and whether its unit can be established against the rig
        configuration (a problem in its report when not); the bus is released after."""
        bus = can.Bus(interface=self.interface, channel=self.channel, bitrate=self.bitrate)
        network = canopen.Network(bus)
        network.NOTIFIER_CYCLE = 0.05
        try:
            network.connect()
            network.nmt.state = "PRE-OPERATIONAL"
            deadline = time.monotonic() + self.connect_timeout
            reports = []
            for leg, settings in enumerate(self.drive_settings.legs, start=1):
                node = network.add_node(settings.node_id, canopen.ObjectDictionary())
                sdo = self._answering(NodeSdo(self.url, node, f"leg {leg} (node {node.id})", SDO_TIMEOUT), deadline)
                eds = eds_objects(settings.eds, sdo.node_id, settings.where or "[drives]") if settings.eds else None
                report = inspect_drive(sdo, leg, eds)
                if not report.problems:
                    try:
                        leg_scaling(self.url, report, settings, self.table.geometry)
                    except DriveSetupError as exc:
                        report.problems.append(str(exc).split(f"{self.url}: ", 1)[-1])
                reports.append(report)
            return reports
        finally:
            network.disconnect()

    def _drive_delays(self, sdo: NodeSdo, report: DriveReport) -> tuple[int, int]:
        """(target delay, feedback delay) [µs] of a drive: its profile's objects, else the configuration's, else one
        cycle and 0; a profile's value the configuration contradicts is refused."""
        settings = self.drive_settings
        configured = (settings.target_delay_s, settings.feedback_delay_s)
        fallback = (self.period_ns // 1000, 0)
        values = []
        for name, index, given, default in zip(("target delay", "feedback delay"),
                                                (report.profile.target_delay if report.profile else None,
                                                 report.profile.feedback_delay if report.profile else None),
                                                configured, fallback, strict=True):
            given_us = None if given is None else round(given * 1e6)
            if index is None:
                values.append(default if given_us is None else given_us)
                continue
            value = sdo.read(index, 0, U32, name)
            if given_us is not None and given_us != value:
                raise DriveSetupError(f"{self.url}: {sdo.what}: its {name} is {value} µs (0x{index:04X}), the rig "
                                      f"configuration says {given_us} µs ([drives])")
            values.append(value)
        return values[0], values[1]

    def _configure_drive(self, link: DriveLink, sdo: NodeSdo, report: DriveReport) -> None:
        """Write a checked drive's set-up: watching, cycle, limits in its units, CSP, PDO maps; its callbacks."""
        heartbeat_ms = round(HEARTBEAT_PERIOD * 1000)
        if report.consumes_heartbeat:
            sdo.write(drive_od.CONSUMER_HEARTBEAT_TIME, 1, U32,
                      heartbeat_consumer_entry(MASTER_NODE_ID, round(CONSUMER_TIME * 1000)), "consumer heartbeat time")
            sdo.write(drive_od.PRODUCER_HEARTBEAT_TIME, 0, U16, heartbeat_ms, "producer heartbeat time")
        else:  # guarded (inspect_drive refused a drive that is neither)
            if report.has(drive_od.PRODUCER_HEARTBEAT_TIME):
                sdo.write(drive_od.PRODUCER_HEARTBEAT_TIME, 0, U16, 0, "producer heartbeat time (off: guarded)")
            sdo.write(drive_od.GUARD_TIME, 0, U16, heartbeat_ms, "guard time")
            sdo.write(drive_od.LIFE_TIME_FACTOR, 0, U8, math.ceil(CONSUMER_TIME / HEARTBEAT_PERIOD),
                      "life time factor")
        if report.has(drive_od.SYNC_COUNTER_OVERFLOW):
            sdo.write(drive_od.SYNC_COUNTER_OVERFLOW, 0, U8, self.sync_counter, "SYNC counter overflow value")
        if report.has(drive_od.COMMUNICATION_CYCLE_PERIOD):
            sdo.write(drive_od.COMMUNICATION_CYCLE_PERIOD, 0, U32, self.period_ns // 1000, "communication cycle period")
        if report.has(drive_od.INTERPOLATION_TIME_PERIOD, 1):
            self._interpolation_period(sdo)
        scaling = link.scaling
        if report.has(drive_od.SOFTWARE_POSITION_LIMIT, 1) and report.has(drive_od.SOFTWARE_POSITION_LIMIT, 2):
            low, high = scaling.software_position_limits
            sdo.write(drive_od.SOFTWARE_POSITION_LIMIT, 1, I32, low, "min position limit")
            sdo.write(drive_od.SOFTWARE_POSITION_LIMIT, 2, I32, high, "max position limit")
        if report.has(drive_od.MAX_PROFILE_VELOCITY):
            sdo.write(drive_od.MAX_PROFILE_VELOCITY, 0, U32, scaling.speed(self.table.geometry.leg_speed),
                      "max profile velocity")
        if report.has(drive_od.FOLLOWING_ERROR_WINDOW):
            window = self.following_error_window
            sdo.write(drive_od.FOLLOWING_ERROR_WINDOW, 0, U32,
                      WINDOW_OFF if window is None else scaling.distance(window), "following error window")
        sdo.write(drive_od.MODES_OF_OPERATION, 0, I8, drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION, "modes of operation")
        shown = sdo.read(drive_od.MODES_OF_OPERATION_DISPLAY, 0, I8, "modes of operation display")
        if shown != drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION:
            raise DriveSetupError(f"{sdo.where(drive_od.MODES_OF_OPERATION_DISPLAY, 0, 'modes of operation display')}"
                                  f": the drive shows mode {shown} after 0x6060 was set to 8 (CSP): it did not take "
                                  "cyclic synchronous position mode")
        sdo.map_pdo(RPDO1)
        sdo.map_pdo(self.drive_tpdo)
        node = link.node
        assert self._network is not None
        self._network.subscribe(self.drive_tpdo.cob_id(link.node_id),
                                lambda _, data, stamp: self._on_drive(link, bytes(data), stamp))
        node.emcy.add_callback(lambda error: self._on_emcy(link, error))
        if not report.consumes_heartbeat:
            node.nmt.start_node_guarding(HEARTBEAT_PERIOD)

    def _interpolation_period(self, sdo: NodeSdo) -> None:
        """0x60C2 to the SYNC period, read back."""
        try:
            mantissa, index = interpolation_period(self.period_ns // 1000)
        except ValueError as exc:
            raise DriveSetupError(f"{sdo.where(drive_od.INTERPOLATION_TIME_PERIOD, 1, 'interpolation time period')}"
                                  f": {exc}") from None
        sdo.write(drive_od.INTERPOLATION_TIME_PERIOD, 1, U8, mantissa, "interpolation time period value")
        sdo.write(drive_od.INTERPOLATION_TIME_PERIOD, 2, I8, index, "interpolation time index")
        kept = (sdo.read(drive_od.INTERPOLATION_TIME_PERIOD, 1, U8, "interpolation time period value"),
                sdo.read(drive_od.INTERPOLATION_TIME_PERIOD, 2, I8, "interpolation time index"))
        if kept != (mantissa, index):
            raise DriveSetupError(f"{sdo.where(drive_od.INTERPOLATION_TIME_PERIOD, 1, 'interpolation time period')}"
                                  f": written {mantissa} × 10^{index} s, the drive kept {kept[0]} × 10^{kept[1]} s: it "
                                  f"cannot interpolate over the SYNC period ({self.period_ns // 1000} µs)")

    def _configure_sensors(self, deadline: float) -> None:
        """The accelerometers' SYNC TPDO and heartbeat, the detector's event TPDO and heartbeat (the project's own
        nodes: their EDS is in :mod:`protocols.canopen.sensors`)."""
        heartbeat_ms = round(HEARTBEAT_PERIOD * 1000)
        sample_delays = set()
        for sensor in self._sensors:
            sdo = self._answering(NodeSdo(self.url, sensor.node, f"accelerometer node 0x{sensor.node.id:02X}",
                                          SDO_TIMEOUT), deadline)
            sdo.write(drive_od.PRODUCER_HEARTBEAT_TIME, 0, U16, heartbeat_ms, "producer heartbeat time")
            sdo.write(drive_od.SYNC_COUNTER_OVERFLOW, 0, U8, self.sync_counter, "SYNC counter overflow value")
            sdo.map_pdo(self.accel_tpdo)
            sample_delays.add(sdo.read(SAMPLE_DELAY, 0, U32, "sample delay"))
            assert self._network is not None

            def on_accel(_: int, data: bytearray, stamp: float, sensor: SensorLink = sensor) -> None:
                self._on_accel(sensor, bytes(data), stamp)

            self._network.subscribe(self.accel_tpdo.cob_id(sensor.node_id), on_accel)
        if len(sample_delays) > 1:
            raise DriveSetupError(f"{self.url}: the accelerometers declare different sample delays "
                                  f"{sorted(sample_delays)}")
        self.sample_delay_ns = sample_delays.pop() * 1000 if sample_delays else 0
        if self._detector is not None:
            node = self._detector.node
            sdo = self._answering(NodeSdo(self.url, node, f"overturn detector node 0x{node.id:02X}", SDO_TIMEOUT),
                                  deadline)
            sdo.write(drive_od.PRODUCER_HEARTBEAT_TIME, 0, U16, heartbeat_ms, "producer heartbeat time")
            sdo.map_pdo(EVENT_TPDO1)
            assert self._network is not None
            self._network.subscribe(EVENT_TPDO1.cob_id(self._detector.node_id),
                                    lambda _, data, stamp: self._on_event(bytes(data), stamp))

    def _answering(self, sdo: NodeSdo, deadline: float) -> NodeSdo:
        """``sdo`` once its node answers (asked until ``deadline`` [s, monotonic]: a node may still be booting)."""
        while True:
            try:
                sdo.node.sdo.upload(drive_od.DEVICE_TYPE, 0)
                return sdo
            except canopen.SdoAbortedError:
                return sdo  # it answered: what it said is for the reads that follow
            except canopen.SdoCommunicationError:
                if time.monotonic() > deadline:
                    raise TableTimeoutError(f"{self.url}: {sdo.what} does not answer SDO within "
                                            f"{self.connect_timeout} s (is it powered, on the bus, at {self.bitrate} "
                                            "bit/s?)") from None

    def close(self) -> None:
        if self._network is None:
            return
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        for link in self._drives:
            link.node.nmt.stop_node_guarding()
        self._network.disconnect()
        self._network = None
        self.feedback.close()
        self.heap.release()
