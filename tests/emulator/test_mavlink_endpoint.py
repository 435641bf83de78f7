"""The emulator's MAVLink endpoint: a datagram counts at the time it reached the socket, however late it is read."""

from __future__ import annotations

import secrets
import time
from typing import Any, cast

import numpy as np
import pytest

from analysis.table.model import TableModel
from protocols.mavlink import UdpLink, dialect, setpoint_chunks, unpack_setpoint_chunk
from sim_table.controller import ControllerCore, State
from sim_table.mavlink_endpoint import MavlinkEndpoint

pytestmark = pytest.mark.integration  # opens sockets (tests/conftest.py)

STALL_NS = 150_000_000
"""How long the endpoint is left unread: longer than the controller's 100 ms heartbeat watchdog."""


def arm_heartbeats_of(endpoint: MavlinkEndpoint, host: UdpLink) -> None:
    """Have ``host`` arm the table of ``endpoint`` (only the arming host's heartbeats feed the watchdog)."""
    d = dialect()
    for _ in range(2):  # a host keeps its heartbeat up before it arms (sim_table.arming)
        host.send(d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, d.MAV_STATE_ACTIVE, 3))
    host.send(d.MAVLink_command_long_message(1, 1, d.MAV_CMD_SHAKETABLE_ARM, 0, 0, 0, 0, 0, 0, 0, 0))
    deadline = time.monotonic() + 5.0
    actions: list[Any] = []
    while len(actions) < 3:
        assert time.monotonic() < deadline, "the heartbeats and the ARM did not arrive"
        actions += endpoint.take(time.monotonic_ns())
    core = ControllerCore(TableModel())
    for _, action in actions:
        action(core)
    assert core.state is State.ARMED


def test_a_heartbeat_sent_as_soon_as_the_endpoint_exists_counts_at_the_time_it_came() -> None:
    """Linux stamps arriving packets only while a socket of the machine asks for stamps, and turns the stamping on
    from a kernel thread after the first one asks: a datagram that comes before is stamped when it is read. The
    endpoint waits for the stamping in its constructor, so a heartbeat sent at once and read after a stall counts
    at the time it came (before, on a loaded machine, the first heartbeat of the test below was stamped at the
    read, 150 ms late, and held all five back). Each round starts after a pause that lets the kernel turn the
    stamping off again when no other socket asks for it."""
    key = secrets.token_bytes(32)
    d = dialect()
    for _ in range(10):
        time.sleep(0.1)
        endpoint = MavlinkEndpoint(("127.0.0.1", 0), key, clock=lambda ns: ns)
        host = UdpLink.open(peer=endpoint.address, source_system=255, source_component=190, key=key, link_id=1)
        try:
            before = time.monotonic_ns()
            host.send(d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0,
                                                  d.MAV_STATE_ACTIVE, 3))
            after = time.monotonic_ns()
            time.sleep(STALL_NS * 1e-9)
            arrivals = [arrival for arrival, _ in endpoint.take(time.monotonic_ns())]
        finally:
            host.sock.close()
            endpoint.close()
        assert len(arrivals) == 1, endpoint.counters
        assert before - 1_000_000 <= arrivals[0] <= after + 1_000_000


def test_heartbeats_read_after_a_stall_count_at_the_times_they_came() -> None:
    """The endpoint's receive thread not started (its process not scheduled, as on a loaded machine): five
    heartbeats 20 ms apart wait in the socket; 150 ms after the last one the tick thread's ``take`` drains them,
    each stamped between the moments just before and just after its ``sendto`` (loopback delivers within the
    call), not at the read, which came 150 ms or more later."""
    key = secrets.token_bytes(32)
    endpoint = MavlinkEndpoint(("127.0.0.1", 0), key, clock=lambda ns: ns)  # controller time = host time
    host = UdpLink.open(peer=endpoint.address, source_system=255, source_component=190, key=key, link_id=1)
    d = dialect()
    try:
        arm_heartbeats_of(endpoint, host)
        windows = []
        for _ in range(5):
            before = time.monotonic_ns()
            host.send(d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0,
                                                  d.MAV_STATE_ACTIVE, 3))
            windows.append((before, time.monotonic_ns()))
            time.sleep(0.02)
        time.sleep(STALL_NS * 1e-9)
        read_at = time.monotonic_ns()
        arrivals = [arrival for arrival, _ in endpoint.take(read_at)]
        seen = endpoint.counters  # what the endpoint made of the datagrams, for a failure's message
    finally:
        host.sock.close()
        endpoint.close()
    assert len(arrivals) == 5, seen
    slack = 1_000_000  # the real-time to monotonic conversion, read once per datagram
    for arrival, (before, after) in zip(arrivals, windows, strict=True):
        assert before - slack <= arrival <= after + slack
    assert read_at - arrivals[-1] >= STALL_NS


def test_a_chunks_second_copy_after_the_next_chunk_is_not_unpacked_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """The host sends chunk k, then k − 1 again (``drivers.chunked``): chunks 0, 1, 0, 2, 1 are unpacked once
    each (three unpacks, not five), and every copy plays the same samples as its first."""
    import sim_table.mavlink_endpoint as module

    unpacked: list[int] = []

    def counting(msg: Any) -> Any:
        unpacked.append(msg.chunk_seq)
        return unpack_setpoint_chunk(msg)

    monkeypatch.setattr(module, "unpack_setpoint_chunk", counting)
    key = secrets.token_bytes(32)
    endpoint = MavlinkEndpoint(("127.0.0.1", 0), key, clock=lambda ns: ns)
    host = UdpLink.open(peer=endpoint.address, source_system=255, source_component=190, key=key, link_id=1)
    poses = np.linspace(0.0, 0.01, 3 * 8 * 6).reshape(-1, 6)
    chunks = setpoint_chunks(poses, 1_000_000_000, 1_000_000)
    try:
        for k in (0, 1, 0, 2, 1):
            host.send(chunks[k])
        deadline = time.monotonic() + 5.0
        actions: list[Any] = []
        while len(actions) < 5:
            assert time.monotonic() < deadline, f"{len(actions)} of the 5 chunks arrived: {endpoint.counters}"
            actions += endpoint.take(time.monotonic_ns())
    finally:
        host.sock.close()
        endpoint.close()
    assert unpacked == [0, 1, 2]
    played: list[tuple[int, np.ndarray]] = []

    class Recorder:
        def chunk(self, seq: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray, *_: Any) -> None:
            played.append((seq, samples))

    for _, action in actions:
        action(cast(ControllerCore, Recorder()))
    assert [seq for seq, _ in played] == [0, 1, 0, 2, 1]
    for seq, samples in played:
        np.testing.assert_array_equal(samples, poses[8 * seq: 8 * seq + 8].astype(np.float32))
