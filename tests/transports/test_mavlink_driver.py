"""The MAVLink driver against the emulator: real UDP on 127.0.0.1, the emulator a separate process
(``python -m sim_table``) on a free port, real pymavlink on both ends; hand-driven hosts (:class:`RawHost`) play
the unsigned, forged and silent senders. Assertions are about what was delivered and how the table behaved,
never about wall-clock times (those are in ``benchmarks/stream.py``)."""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import re
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.controller import (
    CommandRejectedError,
    StreamAbortedError,
    TableError,
    TableLinkLostError,
    TableStatus,
    open_table,
    register_scheme,
)
from drivers.mavlink import MavlinkTable
from protocols.mavlink import (
    ACCEL_PER_BATCH,
    REPLAY_WINDOW,
    SETPOINTS_PER_CHUNK,
    UdpLink,
    accel_batches,
    dialect,
    enable_signing,
    setpoint_chunks,
    tilt_batches,
)
from protocols.mavlink.signing import signing_timestamp
from protocols.signing_key import write_signing_key
from rig.drive import prepare_drive
from rig.emulator import EmulatorProcess
from rig.records import load_record
from tests.helpers import table_checks
from tests.helpers.streams import drive_excerpt, stream_and_check, surge
from tests.helpers.tables import SharedTable

D = dialect()
LISTEN = "mavlink://127.0.0.1:0"


# ----- the emulator process -----------------------------------------------------------------------------------


def mavlink_address(emulator: EmulatorProcess) -> tuple[str, int]:
    """(host, port) of a ``mavlink://HOST:PORT`` emulator."""
    host, port = emulator.url.removeprefix("mavlink://").rsplit(":", 1)
    return host, int(port)


def start_emulator(*flags: str, key_file: Path | None = None) -> EmulatorProcess:
    return EmulatorProcess.start(LISTEN, *flags, key_file=key_file)



@pytest.fixture(scope="module")
def key_file(shared_key_file: Path) -> Path:
    """The shared tables' signing key, also for this module's tests that start an emulator of their own."""
    return shared_key_file


@pytest.fixture
def plain(shared_mavlink_table: SharedTable) -> EmulatorProcess:
    """The session's emulator without bodies, at rest and checked so before each test (``tests/helpers/tables.py``)."""
    return shared_mavlink_table.emulator


# ----- a hand-driven host -------------------------------------------------------------------------------------


class RawHost(table_checks.Host):
    """A host on its own socket with ids (system, 190): signs with ``key`` if given (starting at ``timestamp``),
    sends heartbeats at ``heartbeat_rate`` [Hz] while ``beating``, collects statuses and COMMAND_ACKs."""

    per_chunk = SETPOINTS_PER_CHUNK

    def __init__(self, address: tuple[str, int], key: bytes | None = None, *, system: int = 250,
                 timestamp: int | None = None, heartbeat_rate: float = 20.0) -> None:
        self.heartbeat_period = 1.0 / heartbeat_rate
        self.link = UdpLink.open(("127.0.0.1", 0), address, source_system=system, source_component=190)
        if key is not None:
            enable_signing(self.link.mav, key, link_id=0, timestamp=timestamp)
        self.beating = True
        self.beats = 0  # heartbeats sent
        self.armed = False  # an ARM of this host was accepted: it owns the table (releases it on close)
        self.statuses: list[Any] = []
        self.acks: list[Any] = []
        self.arrivals: list[Any] = []  # statuses and COMMAND_ACKs in the order they arrived
        self._lock = threading.Lock()
        self._running = True
        self._threads = [threading.Thread(target=self._receive, daemon=True),
                         threading.Thread(target=self._heartbeat, daemon=True)]
        for thread in self._threads:
            thread.start()

    def send(self, msg: Any) -> None:
        with self._lock:
            self.link.send(msg)

    def _receive(self) -> None:
        while self._running:
            for msg in self.link.receive(0.05):
                if msg.get_type() == "SHAKETABLE_STATUS":
                    self.statuses.append((time.monotonic_ns(), msg))
                    self.arrivals.append(msg)
                elif msg.get_type() == "COMMAND_ACK":
                    self.acks.append(msg)
                    self.arrivals.append(msg)

    def _heartbeat(self) -> None:
        while self._running:
            if self.beating:
                self.send(D.MAVLink_heartbeat_message(D.MAV_TYPE_GCS, D.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))
                self.beats += 1
            time.sleep(self.heartbeat_period)

    def command(self, name: str, *params: float) -> str:
        """Send COMMAND_LONG MAV_CMD_SHAKETABLE_<NAME> once; the result of its ACK (``"accepted"``, ``"denied"``, …).
        An ARM waits until this host has sent two heartbeats: the controller arms only a host that keeps its
        heartbeat up (``sim_table.arming``)."""
        deadline = time.monotonic() + 5.0
        while name == "arm" and self.beating and self.beats < 2:
            assert time.monotonic() < deadline, "the host sent no heartbeats"
            time.sleep(self.heartbeat_period / 4)
        command = getattr(D, f"MAV_CMD_SHAKETABLE_{name.upper()}")
        values = [*params] + [0.0] * (7 - len(params))
        result = self.answer(command, lambda: self.send(D.MAVLink_command_long_message(1, 1, command, 0, *values)))
        self.armed |= name == "arm" and result == "accepted"
        return result

    def replay(self, frame: bytes) -> str:
        """Send a captured COMMAND_LONG frame as it is, from this host's socket; the result of its ACK."""
        command = D.MAVLink(None).decode(bytearray(frame)).command  # no key: the signature is not checked
        return self.answer(command, lambda: self.link.sock.sendto(frame, self.link.peer))

    def answer(self, command: int, send: Callable[[], object]) -> str:
        """The result of the first COMMAND_ACK for ``command`` after ``send()``."""
        count = len(self.acks)
        send()
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            answers = [a for a in self.acks[count:] if a.command == command]
            if answers:
                return D.enums["MAV_RESULT"][answers[0].result].name.removeprefix("MAV_RESULT_").lower()
            time.sleep(0.005)
        raise AssertionError(f"no COMMAND_ACK for {command}")

    def chunk(self, samples: np.ndarray, t_start_ns: int, seq: int) -> None:
        (chunk,) = setpoint_chunks(samples, t_start_ns, 1_000_000, seq)
        self.send(chunk)

    def state(self, status: Any) -> str:
        return D.enums["SHAKETABLE_STATE"][status.state].name.removeprefix("SHAKETABLE_STATE_").lower()

    def fault(self, name: str) -> int:
        return getattr(D, f"SHAKETABLE_FAULT_{name}")

    def close(self) -> None:
        """Give the table up as a driver does (a signed RELEASE, when it armed it), then stop."""
        if self.armed:
            with contextlib.suppress(AssertionError):  # no answer: the controller is gone
                self.command("release")
        self._running = False
        for thread in self._threads:
            thread.join()
        self.link.close()


# ----- trajectories -------------------------------------------------------------------------------------------


# ----- streaming a prepared drive -------------------------------------------------------------------------------


@pytest.mark.integration
def test_stream_a_prepared_fema_drive_excerpt(key_file: Path) -> None:
    """16.4 s of drive in virtual time (--speed max)."""
    stream_and_check(drive_excerpt(), LISTEN, key_file, SETPOINTS_PER_CHUNK, MavlinkTable)


@pytest.mark.integration
@pytest.mark.slow
def test_stream_the_whole_prepared_fema_drive(key_file: Path) -> None:
    """NORTHR/MUL009 at β = 5°: 42.4 s of drive in real time."""
    stream_and_check(prepare_drive(load_record("fema:NORTHR/MUL009"), angle=math.radians(5)), LISTEN, key_file,
                     SETPOINTS_PER_CHUNK, MavlinkTable, speed="1")


# ----- signatures ---------------------------------------------------------------------------------------------


@pytest.mark.integration
def test_unsigned_or_forged_motion_is_refused_stopping_is_not(plain: EmulatorProcess, key_file: Path) -> None:
    with open_table(plain.url, key_file=str(key_file)) as table:
        before = table.status()
        unsigned = RawHost(mavlink_address(plain), system=255)
        forged = RawHost(mavlink_address(plain), secrets.token_bytes(32), system=255,  # the driver's own ids and link,
                         timestamp=signing_timestamp(time.time() + 3600))  # a timestamp an hour ahead
        try:
            assert unsigned.command("arm") == "denied"
            assert forged.command("arm") == "denied"
            assert unsigned.command("stop") == "accepted"
            after = table.wait_for_status(lambda s: s.refused_commands >= before.refused_commands + 2, 2)
            assert after.refused_commands == before.refused_commands + 2 and after.state == before.state
            assert "UNSIGNED_COMMAND" in after.faults
            # it arms: the forged timestamp did not lock the real host out
            table_checks.motion_from_others_is_refused(table, (unsigned, forged), before.refused_commands + 2)
        finally:
            unsigned.close()
            forged.close()


@pytest.mark.integration
def test_a_wrong_key_is_refused_with_a_clear_error(plain: EmulatorProcess, tmp_path: Path) -> None:
    table_checks.wrong_key_is_refused(plain.url, tmp_path)


# ----- a local process attacking the link (issue 25) ---------------------------------------------------------


FORGED_OVERTURNS = 58
"""Fake overturns sent by a local process (issue 25: 58 fake against 2 real went into the record)."""


@pytest.mark.integration
@pytest.mark.parametrize("forger_key", ["none", "wrong"])
def test_telemetry_forged_by_a_local_process_is_dropped_and_counted(plain: EmulatorProcess, key_file: Path,
                                                                     forger_key: str) -> None:
    """A process on the host sends to the driver's UDP port, with the controller's ids: overturn events, an
    accelerometer batch of 50 m/s², a FAULTED status with a DRIVE fault — unsigned, or signed with another key.
    None reaches the feedback (the record); each is counted once."""
    with open_table(plain.url, key_file=str(key_file)) as table:
        assert isinstance(table, MavlinkTable) and table._link is not None
        detections, accelerations, statuses = table.detections(), table.accelerations(), table.statuses()
        forger = UdpLink.open(peer=table._link.local_address, source_system=1, source_component=1)
        if forger_key == "wrong":
            enable_signing(forger.mav, secrets.token_bytes(32), link_id=0)
        try:
            for k in range(FORGED_OVERTURNS):
                forger.send(D.MAVLink_shaketable_overturn_event_message(1_000_000 + k, 0, 1, 1.2, k))
            (accel,) = accel_batches(np.full((ACCEL_PER_BATCH, 3), 50.0), 0, 0, 1_000_000, 0)
            forger.send(accel)
            forger.send(D.MAVLink_shaketable_status_message(0, D.SHAKETABLE_STATE_FAULTED, 0, 0, 0,
                                                            D.SHAKETABLE_FAULT_DRIVE, 0, [0.0] * 6, 0, 0))
        finally:
            forger.close()
        counter = "refused_unsigned" if forger_key == "none" else "refused_bad_signature"
        forged = FORGED_OVERTURNS + 2
        table.wait(lambda: table.link_stats().get(counter, 0) >= forged, 5)
        table.wait_for_status(lambda s: True, 2)  # a real status after the forged ones
        stats = table.link_stats()
    assert detections.drain() == []
    assert all(np.abs(batch.samples).max() < 20.0 for batch in accelerations.drain())  # at rest: about g
    seen = statuses.drain()
    assert seen and all("DRIVE" not in status.faults for status in seen)
    assert stats[counter] == forged, {k: v for k, v in stats.items() if "refused" in k or "drop" in k or "stale" in k}


@pytest.mark.integration
def test_heartbeats_of_other_processes_do_not_keep_an_armed_table_armed(plain: EmulatorProcess,
                                                                        key_file: Path) -> None:
    """The host that armed the table dies; an unsigned process and a signed host that did not arm keep sending
    heartbeats at 50 Hz: the table stops (HEARTBEAT_LOST) within the watchdog, as if nobody sent any (issue 25:
    unsigned heartbeats of a third process kept it armed)."""
    key = bytes.fromhex(key_file.read_text())
    address = mavlink_address(plain)
    armer = RawHost(address, key, heartbeat_rate=50.0)
    intruder = RawHost(address, system=7, heartbeat_rate=50.0)
    observer = RawHost(address, key, system=8, heartbeat_rate=50.0)
    try:
        observer.wait(lambda s: observer.state(s) in ("idle", "armed", "faulted", "emergency_stopped"), 15)
        assert armer.command("arm") == "accepted"
        observer.wait(lambda s: observer.state(s) == "armed", 2)
        armer.beating = False  # killed
        stopped = observer.wait(lambda s: observer.state(s) != "armed", 5)
        assert stopped.faults & observer.fault("HEARTBEAT_LOST")
        assert intruder.statuses == []  # unsigned heartbeats make no peer: nothing is sent to it
    finally:
        for host in (armer, intruder, observer):
            host.close()


@pytest.mark.integration
def test_an_arm_without_the_heartbeat_kept_up_is_refused_with_the_controllers_reason(
        plain: EmulatorProcess, key_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A host whose heartbeat comes once a second (a ground station's default) arms: the controller refuses with a
    STATUSTEXT saying why, then TEMPORARILY_REJECTED; the driver's error carries that reason, not a generic
    refusal, and the table stays unarmed."""
    import drivers.mavlink

    monkeypatch.setattr(drivers.mavlink, "HEARTBEAT_RATE", 1.0)
    with open_table(plain.url, key_file=str(key_file)) as table:  # the shared table: at rest, checked so
        time.sleep(1.2)  # two beats 1 s apart: beats, but too far apart for the 1 s watchdog
        with pytest.raises(CommandRejectedError) as refused:
            table.arm()
        assert table.status().state != "armed"
    assert re.fullmatch(r"ARM refused: gap \d+\.\d\ds; HEARTBEAT <=0\.50s apart \(table \w+\)",
                        str(refused.value)), str(refused.value)


def captured_commands(key: bytes, unix_time: float, *commands: tuple[str, float]) -> list[bytes]:
    """COMMAND_LONG frames (name, param1) as the driver signed them at ``unix_time`` [s] (system 255, component
    190, link 0): what a capture of the link holds."""
    mav = D.MAVLink(None, srcSystem=255, srcComponent=190)
    enable_signing(mav, key, link_id=0, timestamp=signing_timestamp(unix_time))
    return [D.MAVLink_command_long_message(1, 1, getattr(D, f"MAV_CMD_SHAKETABLE_{name.upper()}"), 0, param,
                                           *[0.0] * 6).pack(mav) for name, param in commands]


@pytest.mark.integration
def test_a_signed_arm_and_tilt_captured_before_a_restart_are_refused(tmp_path: Path) -> None:
    """Captured signed ARM and SET_TILT (a stream stamped 36 s ago, as in issue 25) replayed to a controller that
    has just started: refused as unsigned; a host stamping from the wall clock arms. A key of its own: no replay
    state kept beside it yet (the shared key's holds the shared table's stamps, which a restart would take up)."""
    key_file = tmp_path / "rig.key"
    write_signing_key(key_file)
    key = bytes.fromhex(key_file.read_text())
    emulator = start_emulator(key_file=key_file)
    try:
        address = mavlink_address(emulator)
        replayer = RawHost(address, system=251)
        host = RawHost(address, key, system=252)
        captured = captured_commands(key, time.time() - 36.0, ("arm", 0.0), ("set_tilt", math.radians(4.0)))
        late = captured_commands(key, time.time() - REPLAY_WINDOW - 1.0, ("arm", 0.0))
        try:
            assert [replayer.replay(frame) for frame in captured + late] == ["denied"] * 3
            assert host.command("arm") == "accepted"
            assert host.command("disarm") == "accepted"
        finally:
            for raw in (replayer, host):
                raw.close()
    finally:
        counters = emulator.stop()
    assert counters["refused_commands"] == 3
    assert counters["link"]["stale_signatures"] >= 3


JUNK_BYTES = 30 << 20
"""The junk flood of issue 25 [bytes]: at least this much is sent before the host starts connecting."""


@pytest.mark.integration
def test_a_junk_flood_does_not_keep_the_host_from_connecting(shared_mavlink_table: SharedTable, key_file: Path) -> None:
    """A local process floods the controller's port with junk datagrams (1 KiB of random bytes each), 30 MB before
    the host starts connecting and on until it is done: it connects, arms and disarms, and the junk is counted."""
    emulator = shared_mavlink_table.emulator
    address = mavlink_address(emulator)
    junk = np.random.default_rng(25).bytes(1024)
    flooded, done = threading.Event(), threading.Event()
    sent = [0]

    def flood() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            while not done.is_set():
                try:
                    sent[0] += sock.sendto(junk, address)
                except OSError:  # ENOBUFS: the kernel's queue is full, try again
                    time.sleep(0.0001)
                if sent[0] >= JUNK_BYTES:
                    flooded.set()

    thread = threading.Thread(target=flood, daemon=True)
    thread.start()
    try:
        assert flooded.wait(60)
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            table.disarm()
        assert thread.is_alive()  # the flood went on all along
    finally:
        done.set()
        thread.join()
    counters = shared_mavlink_table.counters()
    assert counters["link"]["junk_datagrams"] > 0 and counters["commands_accepted"] >= 2, counters


# ----- watchdogs, stops, faults -------------------------------------------------------------------------------


@pytest.mark.integration
@pytest.mark.parametrize("silent", ["heartbeat", "stream"])
def test_a_silent_host_gets_the_table_stopped_and_home(plain: EmulatorProcess, key_file: Path, silent: str) -> None:
    host = RawHost(mavlink_address(plain), bytes.fromhex(key_file.read_text()))
    table_checks.silent_host_gets_the_table_stopped(host, silent)


@pytest.mark.integration
def test_emergency_stop_mid_stream_stops_at_once_and_stays(key_file: Path) -> None:
    table_checks.emergency_stop_mid_stream(LISTEN, key_file)


@pytest.mark.integration
def test_commands_survive_packet_loss_and_run_once(key_file: Path) -> None:
    """20 % of the datagrams lost both ways: retries get every command through, de-duplication runs each once."""
    table_checks.commands_survive_loss(LISTEN, key_file, MavlinkTable, 0.05, "packets")


@pytest.mark.integration
def test_injected_drive_fault_under_delay_stops_the_stream(monkeypatch: pytest.MonkeyPatch, key_file: Path) -> None:
    """The key from the environment on both ends; 10 ms added each way; a drive fault 1 s into the stream; the
    controller's clock at twice real time."""
    table_checks.injected_drive_fault_under_delay(LISTEN, key_file, monkeypatch)


@pytest.mark.integration
def test_a_motions_final_answer_comes_after_the_status_that_shows_it(key_file: Path) -> None:
    """The final COMMAND_ACK of SET_TILT and HOME arrives after a status that shows the move over (armed, at its
    target) and before one taken after it. (Sent as they were made, an ACK went before the statuses of its batch of
    ticks, the status of the tick the move ended in among them; at twice real time a batch has four ticks.)"""
    emulator = start_emulator("--speed", "2", key_file=key_file)
    host = RawHost(mavlink_address(emulator), bytes.fromhex(key_file.read_text()), heartbeat_rate=50.0)
    try:
        assert host.command("arm") == "accepted"
        for name, params, pitch in (("set_tilt", (math.radians(1),), math.radians(1)), ("home", (), 0.0)):
            command = getattr(D, f"MAV_CMD_SHAKETABLE_{name.upper()}")
            start = len(host.arrivals)
            assert host.command(name, *params) == "in_progress"
            deadline = time.monotonic() + 10
            final = None
            while final is None and time.monotonic() < deadline:
                time.sleep(0.01)
                arrived = host.arrivals[start:]
                final = next((k for k, m in enumerate(arrived)
                              if m.get_type() == "COMMAND_ACK" and m.command == command and m.progress == 100), None)
            assert final is not None, f"no final answer to {name}"
            while len(host.arrivals) < start + final + 2:
                time.sleep(0.01)
            arrived = host.arrivals[start:]
            before, after = arrived[final - 1], arrived[final + 1]
            assert arrived[final].result == D.MAV_RESULT_ACCEPTED, (name, [
                (host.state(m), m.faults, m.t_ns) for m in arrived if m.get_type() == "SHAKETABLE_STATUS"][-3:])
            for status in (before, after):
                assert status.get_type() == "SHAKETABLE_STATUS" and host.state(status) == "armed"
                assert status.pose[4] == pytest.approx(pitch, abs=1e-4)
            assert after.t_ns >= before.t_ns
    finally:
        host.close()
        emulator.stop()


@pytest.mark.integration
def test_moves_are_shown_by_the_status_when_they_return(key_file: Path) -> None:
    table_checks.moves_are_shown_by_the_status(start_emulator("--speed", "2", "--delay", "30",
                                                              key_file=key_file), key_file)


@pytest.mark.integration
@pytest.mark.parametrize(("lead", "stopped_by"), [(0.2, "UNDERRUN"), (3.0, "STREAM_SILENT")])
def test_a_stalled_stream_stops_the_table_home(key_file: Path, lead: float, stopped_by: str) -> None:
    """The emulator drops every chunk from 0.5 s after the stream started (its clock at 2x: its 1 s watchdog is 2 s
    of controller time). A lead shorter than that: the buffer runs dry first, an underrun, a controlled stop; a
    longer one: the stream watchdog trips first, with samples still buffered. Either way the table goes home."""
    emulator = start_emulator("--stall-at", "0.5", "--speed", "2", key_file=key_file)
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            t, poses = surge(6.0, lambda t: 0.02 * np.sin(2 * np.pi * t))
            with pytest.raises(StreamAbortedError, match=stopped_by):
                table.stream(t, poses, lead=lead)
            final = table.wait_for_state("faulted", 10)
    finally:
        counters = emulator.stop()
    assert set(final.faults) == {stopped_by} and final.underruns == (stopped_by == "UNDERRUN")
    np.testing.assert_allclose(final.pose, np.zeros(6), atol=1e-4)
    assert counters["link"]["chunks_stalled"] > 0 and counters["watchdog_stops"] == (stopped_by == "STREAM_SILENT")


# ----- telemetry ----------------------------------------------------------------------------------------------


def test_tilt_batches_are_published_and_each_bodys_lost_ones_counted() -> None:
    """SHAKETABLE_TILT_BATCHes as received (no socket): each becomes a TiltBatch of its body with its timing and
    angles; a skipped batch_seq of a body counts as lost batches of that body only, across the sequence's wrap."""
    table = MavlinkTable("mavlink://127.0.0.1:9")
    tilts = table.tilts()
    body0 = tilt_batches(np.linspace(-0.2, 0.9, 59 * 4), 0, 5_000_000, 5_000_000, first_seq=2**32 - 2)
    body3 = tilt_batches(np.zeros(59 * 2), 3, 5_000_000, 5_000_000)
    for message in [body0[0], body3[0], body0[2], body3[1], body0[3]]:  # body 0 loses seq 2^32 - 1
        table._dispatch(message, 0)
    got = tilts.drain()
    assert [(b.body_id, b.seq) for b in got] == [(0, 2**32 - 2), (3, 0), (0, 0), (3, 1), (0, 1)]
    assert table.link_stats()["tilt_batches_lost"] == table.tilt_batches_lost == 1
    np.testing.assert_array_equal(got[2].angles, np.linspace(-0.2, 0.9, 59 * 4)[118:177].astype(np.float32))
    assert got[2].angles.shape == (59,) and got[2].t_start_ns == 5_000_000 + 118 * 5_000_000
    assert np.all(np.diff(got[2].times_ns()) == 5_000_000)


# ----- connection and registry --------------------------------------------------------------------------------


def test_urls_pick_the_backend_and_options_reach_it(key_file: Path) -> None:
    table = open_table("mavlink://127.0.0.1:14600", key_file=str(key_file), retries=7)
    assert isinstance(table, MavlinkTable) and table.address == ("127.0.0.1", 14600) and table.retries == 7
    register_scheme("loopback-test", lambda url, **options: MavlinkTable("mavlink://127.0.0.1:9", **options))
    assert open_table("loopback-test://anything", command_timeout=0.3).command_timeout == 0.3
    with pytest.raises(ValueError, match=r"unknown scheme 'can'; known: .*mavlink"):
        open_table("can://vcan0")
    with pytest.raises(ValueError, match="HOST:PORT"):
        open_table("mavlink://127.0.0.1")
    with pytest.raises(TableError, match="no status received"):
        table.status()


@pytest.mark.integration
def test_connect_without_a_controller_times_out(key_file: Path) -> None:
    table_checks.connect_without_a_controller_times_out("mavlink://127.0.0.1:9", key_file)


@pytest.mark.integration
def test_rig_emulate_runs_the_emulator_in_the_foreground(tmp_path: Path, key_file: Path) -> None:
    """``rig emulate`` (registered on an app of its own here) becomes the emulator; SIGINT stops it cleanly."""
    code = ("import typer\nfrom rig.cli import emulate as cli_emulate\napp = typer.Typer()\ncli_emulate.register(app)\n"
            "@app.callback()\ndef main() -> None: pass\napp()")
    counters = tmp_path / "counters.json"
    proc = subprocess.Popen([sys.executable, "-c", code, "emulate", "--listen", "mavlink://127.0.0.1:0",
                             "--key-file", str(key_file), "--counters", str(counters)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    url = re.search(r"mavlink://\S+", proc.stderr.readline())
    assert url is not None
    with open_table(url.group(0), key_file=str(key_file)) as table, table.statuses() as statuses:
        assert next(iter(statuses)).state == "idle"
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=20) == 0
    assert json.loads(counters.read_text())["state"] == "idle"
    bad = subprocess.run([sys.executable, "-c", code, "emulate", "--speed", "2"], capture_output=True, text=True)
    assert bad.returncode == 2 and "--listen" in bad.stderr


# ----- an emulator process that is not scheduled for a while ------------------------------------------------------


@pytest.mark.integration
def test_an_emulator_stopped_for_300_ms_mid_stream_plays_on(key_file: Path) -> None:
    """The emulator's process stopped (SIGSTOP) for 300 ms in the middle of a 1x stream, as a loaded machine may
    leave it unscheduled: the host's heartbeats and chunks of those 300 ms wait in its socket, and the endpoint
    counts them at the times the kernel stamped them (sim_table/mavlink_endpoint.py), so the stream plays to its end
    with no fault and no underrun; the host, whose link timeout (0.5 s) the stall stays under, goes on."""
    emulator = start_emulator(key_file=key_file)
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            t, poses = surge(2.0, lambda t: 0.01 * np.sin(2 * np.pi * t))
            started = threading.Event()

            def stall() -> None:
                started.wait(10)
                time.sleep(0.8)
                emulator.proc.send_signal(signal.SIGSTOP)
                time.sleep(0.3)
                emulator.proc.send_signal(signal.SIGCONT)

            staller = threading.Thread(target=stall)
            staller.start()
            try:
                report = table.stream(t, poses, on_start=lambda _: started.set())  # the default lead, 1 s
            finally:
                staller.join()
            table.disarm()
    finally:
        counters = emulator.stop()
    assert report.final is not None and report.final.faults == () and report.underruns == 0
    assert counters["faults_raised"] == {} and counters["watchdog_stops"] == 0 and counters["samples_late"] == 0
    # the stall happened: the emulator caught up on it (its first late tick was due up to a wake period, 20 ms,
    # after the process stopped)
    assert counters["timing"]["lag_max_ms"] > 250, counters["timing"]


STALL_S = 0.6
"""How long the emulator's process is stopped in the link tests below [s]: beyond the host's link timeout there
(:data:`SHORT_LINK_TIMEOUT_S` plus the grace and a wait slice, 0.4 s at most) and well inside a virtual-time
table's own watchdog (1 s, ``sim_table/process.py`` ``VIRTUAL_WATCHDOG_SECONDS``)."""

SHORT_LINK_TIMEOUT_S = 0.1
"""The host's link timeout in those tests [s] (the rig TOML's ``link_timeout_s``; 0.5 s by default)."""


def _stalled_link(key_file: Path, *flags: str) -> tuple[TableStatus, bool]:
    """Arm an emulator started with ``flags``, stop its process for :data:`STALL_S` and let it go on, waiting for
    a status meanwhile with the host's link checks; (the status before the stall, whether the link was declared
    lost)."""
    emulator = start_emulator(*flags, key_file=key_file)
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            table.link_timeout = SHORT_LINK_TIMEOUT_S
            before = table.status()
            resumed: list[int] = []

            def resume() -> None:
                time.sleep(STALL_S)
                resumed.append(time.monotonic_ns())
                emulator.proc.send_signal(signal.SIGCONT)

            emulator.proc.send_signal(signal.SIGSTOP)
            waker = threading.Thread(target=resume)
            waker.start()
            try:
                table.wait(lambda: bool(resumed) and table.feedback.latest is not None
                           and table.feedback.latest.host_ns > resumed[0], 10.0)
                lost = False
            except TableLinkLostError:
                lost = True
            finally:
                waker.join()
            if not lost:
                table.disarm()
    finally:
        emulator.proc.send_signal(signal.SIGCONT)
        emulator.stop()
    return before, lost


@pytest.mark.integration
def test_a_virtual_time_table_stalled_beyond_the_link_timeout_is_not_taken_for_lost(key_file: Path) -> None:
    """An emulator in virtual time (``--speed max``) says so in its statuses, with its own link watchdog; its
    process stopped longer than the host's link timeout (as a loaded host's run queue holds its tick thread) is
    allowed that watchdog and not declared lost; a table at 1x, stopped as long, still is."""
    before, lost = _stalled_link(key_file, "--speed", "max")
    assert before.virtual_watchdog_s == pytest.approx(1.0)
    assert not lost
    before, lost = _stalled_link(key_file)
    assert before.virtual_watchdog_s == 0.0
    assert lost


class _DownLink:
    """A link whose network is gone: every send fails with ``error`` (an errno)."""

    def __init__(self, error: int) -> None:
        self.mav = type("Mav", (), {"signing": type("Signing", (), {"timestamp": 0})()})()
        self.error = error

    def send(self, msg: Any) -> None:
        raise OSError(self.error, os.strerror(self.error))


def test_a_datagram_the_network_refuses_is_lost_and_counted_not_raised(key_file: Path) -> None:
    """In process (no socket): the interface down, a send is a datagram lost — counted and named when the link is
    declared lost — not an OSError out of the stream or the heartbeat thread; another OSError still raises."""
    table = MavlinkTable("mavlink://10.231.0.2:14600", key_file=str(key_file))
    table._link = _DownLink(errno.ENETUNREACH)  # type: ignore[assignment]
    heartbeat = table.d.MAVLink_heartbeat_message(table.d.MAV_TYPE_GCS, table.d.MAV_AUTOPILOT_INVALID, 0, 0,
                                                  table.d.MAV_STATE_ACTIVE, 3)
    table._send(heartbeat)
    table._send(heartbeat)
    assert table.send_failures == 2 and table.link_stats()["send_failures"] == 2
    assert table._link_lost_detail() == f"; 2 sends failed: {os.strerror(errno.ENETUNREACH)}"
    table._link = _DownLink(errno.EBADF)  # type: ignore[assignment]
    with pytest.raises(OSError, match="Bad file descriptor"):
        table._send(heartbeat)
