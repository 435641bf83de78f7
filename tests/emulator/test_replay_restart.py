"""A controller whose clock is wrong takes no captured signed command (issue 42, item 4): restarted with its clock
60 s behind, it refuses a signed ARM captured 20 s earlier (its streams' stamps were kept in its replay-state file);
a signed message stamped from the future is refused whatever its clock."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest

from analysis.table.model import TableModel
from protocols.mavlink import UdpLink, dialect, enable_signing
from protocols.mavlink.signing import signing_timestamp
from protocols.signing_key import write_signing_key
from rig.emulator import EmulatorProcess
from sim_table.controller import ControllerCore, State
from sim_table.mavlink_endpoint import MavlinkEndpoint

pytestmark = pytest.mark.integration  # opens sockets, starts the emulator (tests/conftest.py)

D = dialect()


def signed_sender(peer: tuple[str, int], key: bytes, unix_time: float, *, link_id: int,
                  system: int = 250) -> UdpLink:
    """A host link to ``peer`` whose next signature is stamped at ``unix_time`` [s]."""
    link = UdpLink.open(("127.0.0.1", 0), peer, source_system=system, source_component=190)
    enable_signing(link.mav, key, link_id=link_id, timestamp=signing_timestamp(unix_time))
    return link


def arm(link: UdpLink) -> bytes:
    """Send a signed ARM on ``link``; its frame as it went out (the capture)."""
    msg = D.MAVLink_command_long_message(1, 1, D.MAV_CMD_SHAKETABLE_ARM, 0, 0, 0, 0, 0, 0, 0, 0)
    link.send(msg)
    return bytes(msg.get_msgbuf())


def heartbeat(link: UdpLink) -> None:
    link.send(D.MAVLink_heartbeat_message(D.MAV_TYPE_GCS, D.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))


def beats(link: UdpLink) -> None:
    """The two heartbeats a host sends before it may arm (``sim_table.arming``)."""
    heartbeat(link)
    heartbeat(link)


def applied(endpoint: MavlinkEndpoint, core: ControllerCore, count: int) -> None:
    """Apply the next ``count`` host messages the endpoint takes to ``core``."""
    deadline = time.monotonic() + 10.0
    taken: list[Any] = []
    while len(taken) < count:
        assert time.monotonic() < deadline, f"{len(taken)} of {count} messages arrived"
        taken += endpoint.take(time.monotonic_ns())
        time.sleep(0.005)
    for _, action in taken:
        action(core)


def test_restarted_with_its_clock_60_s_behind_it_refuses_an_arm_captured_20_s_before(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    key = write_signing_key(tmp_path / "rig.key")
    state = tmp_path / "rig.key.mavlink-replay.json"
    true_time = time.time
    clock_error = [0.0]
    monkeypatch.setattr(time, "time", lambda: true_time() + clock_error[0])  # the controller's clock (and only it
    # reads time.time here: the host's stamps are set by hand)
    now = true_time()

    endpoint = MavlinkEndpoint(("127.0.0.1", 0), key, clock=lambda ns: ns, replay_state=state)
    clock_error[0] = -20.0  # the capture is made 20 s ago, and taken then
    host = signed_sender(endpoint.address, key, now - 20.0, link_id=9)
    core = ControllerCore(TableModel())
    try:
        beats(host)
        captured = arm(host)
        applied(endpoint, core, 3)
        assert core.state is State.ARMED
        clock_error[0] = 0.0  # the host's later messages, up to now
        host.mav.signing.timestamp = signing_timestamp(now)
        heartbeat(host)
        applied(endpoint, core, 1)
    finally:
        endpoint.close()  # the controller stops; its replay state is in the file
    assert [stream for stream, _ in json.loads(state.read_text())["streams"]] == [[9, 250, 190]]

    clock_error[0] = -60.0  # restarted with its clock 60 s behind
    restarted = MavlinkEndpoint(("127.0.0.1", 0), key, clock=lambda ns: ns, replay_state=state)
    replayer = signed_sender(restarted.address, key, now - 20.0, link_id=77, system=251)
    core = ControllerCore(TableModel())
    try:
        replayer.sock.sendto(captured, restarted.address)  # the capture, as it was
        applied(restarted, core, 1)
        arm(replayer)  # another stream stamped 20 s ago, which this controller never heard
        applied(restarted, core, 1)
        assert core.state is State.IDLE and core.counters.refused_commands == 2
        assert restarted.counters.stale_signatures == 2
        on_time = signed_sender(restarted.address, key, true_time(), link_id=5, system=252)
        try:
            beats(on_time)
            arm(on_time)  # a host on time still arms
            applied(restarted, core, 3)
        finally:
            on_time.close()
        assert core.state is State.ARMED
    finally:
        replayer.close()
        host.close()
        restarted.close()


def test_a_signed_arm_stamped_from_the_future_is_denied_and_the_table_stays_idle(tmp_path: Path) -> None:
    """A capture made for a controller whose clock was 60 s behind, 20 s earlier, is 40 s in its future: before
    issue 42 a new stream took any stamp ahead of the clock."""
    key_file = tmp_path / "rig.key"
    key = write_signing_key(key_file)
    with EmulatorProcess.start("mavlink://127.0.0.1:0", "--speed", "max", key_file=key_file) as emulator:
        host, port = emulator.url.removeprefix("mavlink://").rsplit(":", 1)
        ahead = signed_sender((host, int(port)), key, time.time() + 40.0, link_id=3)
        on_time = signed_sender((host, int(port)), key, time.time(), link_id=4, system=252)
        try:
            assert answer(ahead, lambda: arm(ahead)) == "denied"
            beats(on_time)
            assert answer(on_time, lambda: arm(on_time)) == "accepted"
        finally:
            ahead.close()
            on_time.close()
        counters = emulator.stop()
    assert counters["refused_commands"] == 1 and counters["link"]["future_signatures"] == 1
    assert (tmp_path / "rig.key.mavlink-replay.json").exists()


def answer(link: UdpLink, send: Any) -> str:
    """The result of the first COMMAND_ACK to ARM ``link`` receives after ``send()``."""
    send()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        for msg in link.receive(0.05):
            if msg.get_type() == "COMMAND_ACK" and msg.command == D.MAV_CMD_SHAKETABLE_ARM:
                return D.enums["MAV_RESULT"][msg.result].name.removeprefix("MAV_RESULT_").lower()
    raise AssertionError("no COMMAND_ACK")
