"""What the table must do on every transport when it is stopped, faulted, left silent by its host, reached through a
lossy link or by a host without the key: the test bodies the transport tests share. Each transport's test calls one
with what differs there — the emulator's ``listen`` URL, the table class, the names of its link counters, its
hand-driven host. A plain module, imported by the transport tests."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from analysis.table.link import LinkSettings
from drivers.controller import (
    STATUS_TIMEOUT,
    StreamAbortedError,
    StreamReport,
    TableController,
    TableError,
    TableTimeoutError,
    open_table,
)
from protocols.signing_key import KEY_ENV, write_signing_key
from rig.emulator import EmulatorProcess
from tests.helpers.streams import smooth_ramp, surge

# ----- a hand-driven host -------------------------------------------------------------------------------------


class Host:
    """A host that talks to the controller on its own, bypassing the driver; each transport's test has one
    (``RawHost``). Subclasses receive ``statuses`` (arrival host monotonic time [ns], raw status), send heartbeats
    while ``beating``, and say how their transport names states and faults."""

    per_chunk: int
    """Setpoints in one chunk of the transport."""
    statuses: list[tuple[int, Any]]
    beating: bool

    def command(self, name: str, *params: float) -> str:
        """Send command ``name`` (``"arm"``, ``"start_stream"``, …); the controller's answer (``"accepted"``, …)."""
        raise NotImplementedError

    def chunk(self, samples: np.ndarray, t_start_ns: int, seq: int) -> None:
        """Send ``samples`` (at most :attr:`per_chunk` poses, 1 ms apart) as setpoint chunk ``seq``."""
        raise NotImplementedError

    def state(self, status: Any) -> str:
        """The state of a received status, by its name (``"streaming"``, …)."""
        return str(status.state)

    def fault(self, name: str) -> int:
        """The bit of fault ``name`` (``"UNDERRUN"``, …) in a received status's ``faults``."""
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def controller_now(self) -> int:
        """Controller time [ns] estimated from the last status (its delay on loopback is well below 1 ms)."""
        received, status = self.statuses[-1]
        return status.t_ns + time.monotonic_ns() - received

    def wait(self, predicate: Callable[[Any], bool], timeout: float) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.statuses and predicate(self.statuses[-1][1]):
                return self.statuses[-1][1]
            time.sleep(0.005)
        raise AssertionError(f"no matching status; last {self.statuses[-1][1] if self.statuses else None}")


# ----- signatures ---------------------------------------------------------------------------------------------


def motion_from_others_is_refused(table: Any, others: tuple[Host, ...],
                                        refused_before: int) -> StreamReport:
    """Arm ``table`` and stream a 2 s, 1 cm surge (the default lead); meanwhile each of ``others`` (hosts without
    the key) sends 10 chunks of a wild pose (0.2 m) 20 ms ahead, numbered as the real stream is about to number its
    own: every one is refused (``refused_before`` counted before), the stream plays on to its end and the table
    stays within 1 cm. The stream's report."""
    table.arm()
    t, poses = surge(2.0, lambda t: 0.01 * np.sin(2 * np.pi * t))
    result: dict[str, Any] = {}
    streamer = threading.Thread(target=lambda: result.update(report=table.stream(t, poses)),  # the default lead
                                daemon=True)
    statuses = table.statuses()
    streamer.start()
    playing = table.wait_for_status(lambda s: s.state == "streaming" and s.last_chunk_seq >= 5, 2)
    for k in range(10):  # chunk numbers the real stream is about to use, a wild pose 20 ms ahead
        for host in others:
            host.chunk(np.tile([0.2, 0, 0, 0, 0, 0], (host.per_chunk, 1)),
                       table.clock.to_controller(time.monotonic_ns()) + 20_000_000, playing.last_chunk_seq + 10 + 2 * k)
        time.sleep(0.01)
    streamer.join()
    report: StreamReport = result["report"]
    assert report.underruns == 0 and report.final.state == "armed"
    assert report.final.refused_commands == refused_before + 10 * len(others)
    assert "CHUNK_GAP" not in report.final.faults
    assert max(abs(s.pose[0]) for s in statuses.drain()) < 0.0101
    return report


def wrong_key_is_refused(url: str, directory: Path) -> None:
    """A driver with another key (written to ``directory``) does not connect, and says why: the controller's
    messages (signed, as everything it sends) do not verify with its key."""
    other = directory / "other.key"
    write_signing_key(other)
    with pytest.raises(TableError, match="did not verify with this host's signing key: are host and controller "
                                         "using the same signing key"):
        open_table(url, key_file=str(other), connect_timeout=1.0).connect()


# ----- watchdogs, stops, faults -------------------------------------------------------------------------------


def silent_host_gets_the_table_stopped(host: Host, silent: str) -> None:
    """``host`` (with the key) arms, starts a stream and sends a 3 cm surge ramp in real time; 0.4 s in, it stops
    sending ``"heartbeat"``s (the chunks go on, longer than the controller's watchdog, the configured lead ahead —
    with a 50 ms lead a host held up that long on a busy machine let the buffer run dry first: UNDERRUN instead of
    HEARTBEAT_LOST) or ``"stream"`` chunks, 50 ms ahead (the heartbeats go on): the table stops (faulted, home) — by
    HEARTBEAT_LOST, or by the underrun of its buffer, which runs dry after the 50 ms lead, long before the stream
    watchdog. ``host`` is closed after."""
    try:
        host.wait(lambda s: host.state(s) not in ("stopping", "homing", "tilting", "streaming"), 15)
        assert host.command("arm") == "accepted"
        assert host.command("start_stream", 0.0) == "accepted"
        lead_ns = round(LinkSettings().lead_s * 1e9) if silent == "heartbeat" else 50_000_000
        t0 = host.controller_now() + lead_ns
        _, poses = surge(0.4 + 2 * LinkSettings().watchdog_s, lambda t: smooth_ramp(t, 0.03, 0.6))
        for k in range(0, len(poses), host.per_chunk):
            if k == 400:  # 0.4 s into the stream: go silent
                host.beating = silent != "heartbeat"
                if silent == "stream":
                    break
            due = t0 + k * 1_000_000 - lead_ns
            time.sleep(max(0.0, (due - host.controller_now()) * 1e-9))
            host.chunk(poses[k:k + host.per_chunk], t0 + k * 1_000_000, k // host.per_chunk)
            if host.state(host.statuses[-1][1]) != "streaming" and k > 400:
                break  # stopped: no need to go on
        final = host.wait(lambda s: host.state(s) == "faulted", 10)
    finally:
        host.close()
    seen = [host.state(s) for _, s in host.statuses]
    changes = [a for a, b in zip(seen, [*seen[1:], None], strict=True) if a != b]
    assert changes[-3:] == ["streaming", "stopping", "faulted"]
    assert final.faults & host.fault("HEARTBEAT_LOST" if silent == "heartbeat" else "UNDERRUN")
    assert not final.faults & host.fault("UNDERRUN" if silent == "heartbeat" else "STREAM_SILENT")
    np.testing.assert_allclose(final.pose, np.zeros(6), atol=1e-4)  # home


def emergency_stop_while_streaming(table: TableController, t: np.ndarray, poses: np.ndarray, past: float, *,
                                   state: Callable[[], str] | None = None) -> StreamAbortedError:
    """Stream the surge ``poses`` on the armed ``table``; once the table is ``past`` [m], EMERGENCY_STOP: the table
    brakes within a millimetre and stays there in ``emergency_stopped`` (``state()``, by default the table's last
    status), no return home; ARM keeps the pose, HOME goes home. The stream's error."""
    errors: list[BaseException] = []

    def play() -> None:
        try:
            table.stream(t, poses)
        except BaseException as exc:
            errors.append(exc)

    streamer = threading.Thread(target=play)
    streamer.start()
    table.wait_for_status(lambda s: s.pose[0] > past, 10)
    statuses = table.statuses()
    table.emergency_stop()
    streamer.join()
    stopped = table.wait_for_state("emergency_stopped", 1)
    since = stopped.t_ns
    if state is not None:  # the table's own state: a master that is the controller (CANopen) reports the stop
        deadline = time.monotonic() + STATUS_TIMEOUT  # when it sends it, the drives brake at the next SYNC they handle
        while state() != "emergency_stopped" and time.monotonic() < deadline:
            time.sleep(0.001)
        since = time.monotonic_ns()
    table.wait_for_status(lambda s: s.t_ns >= since + 300_000_000, STATUS_TIMEOUT)
    after = [s for s in statuses.drain() if s.t_ns >= since]
    assert (state or (lambda: table.status().state))() == "emergency_stopped"
    surges = np.array([s.pose[0] for s in after])
    assert surges.max() - surges.min() < 0.001  # braked within a millimetre: no return home
    assert surges[-1] > past
    table.arm()
    assert table.status().state == "armed" and table.status().pose[0] == pytest.approx(surges[-1], abs=1e-4)
    table.home()
    np.testing.assert_allclose(table.status().pose, np.zeros(6), atol=1e-4)
    assert len(errors) == 1 and isinstance(errors[0], StreamAbortedError)
    return errors[0]


def emergency_stop_mid_stream(listen: str, key_file: Path) -> None:
    """A 20 cm surge ramp at twice real time, emergency-stopped past 8 cm (see :func:`emergency_stop_while_streaming`):
    the stream ends as emergency-stopped, the emulator counts one emergency stop and no completed stream."""
    emulator = EmulatorProcess.start(listen, "--speed", "2", key_file=key_file)
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            table.arm()
            t, poses = surge(5.0, lambda t: smooth_ramp(t, 0.2, 5.0))  # 0.06 m/s at its fastest
            aborted = emergency_stop_while_streaming(table, t, poses, 0.08)
    finally:
        counters = emulator.stop()
    assert aborted.report.final is not None and aborted.report.final.state == "emergency_stopped"
    assert counters["emergency_stops"] == 1 and counters["streams_completed"] == 0


def commands_survive_loss(listen: str, key_file: Path, table_type: type,
                                command_timeout: float, unit: str, *, counts_unanswered: bool = False) -> None:
    """20 % of the ``unit``s (the emulator's link counts ``packets`` or ``messages``) lost both ways: retries get 40
    commands through, de-duplication runs each once. With ``counts_unanswered`` the driver's link stats count the
    attempts that went unanswered."""
    emulator = EmulatorProcess.start(listen, "--loss", "20", "--seed", "4", key_file=key_file)
    try:
        with table_type(emulator.url, key_file=str(key_file), command_timeout=command_timeout, retries=12) as table:
            for k in range(40):
                table.stop() if k % 2 else table.disarm()  # alternate: no two equal commands in a row
            stats = table.link_stats()
    finally:
        counters = emulator.stop()
    assert counters["commands_accepted"] == 40 and counters["stops"] == 20
    link = counters["link"]
    assert link["duplicate_commands"] > 0 and link[f"{unit}_dropped"] > 0 and link[f"{unit}_not_sent"] > 0
    if counts_unanswered:
        assert stats["command_attempts_unanswered"] > 0


def injected_drive_fault_under_delay(listen: str, key_file: Path, monkeypatch: pytest.MonkeyPatch,
                                           table_type: type | None = None) -> None:
    """The key from the environment on both ends; 10 ms added each way; a drive fault 1 s into the stream; the
    controller's clock at twice real time: the stream aborts for DRIVE, the table ends faulted and home with its tilt
    undone. With ``table_type`` the URL must open one."""
    env = {KEY_ENV: key_file.read_text().strip()}
    monkeypatch.setenv(KEY_ENV, env[KEY_ENV])
    replay_state = key_file.parent / f"env-key.{listen.split(':')[0]}-replay.json"  # no key file to put it beside
    emulator = EmulatorProcess.start(listen, "--delay", "10", "--drive-fault-at", "1.0", "--speed", "2",
                                     "--replay-state", str(replay_state), env=env)
    try:
        with open_table(emulator.url) as table:
            if table_type is not None:
                assert isinstance(table, table_type)
            faults = table.faults()
            table.arm()
            table.set_tilt(math.radians(1))
            assert table.status().state == "armed" and table.status().pose[4] == pytest.approx(math.radians(1),
                                                                                             abs=1e-4)
            t, poses = surge(3.0, lambda t: 0.02 * np.sin(2 * np.pi * t))
            poses[:, 4] = math.radians(1)
            with pytest.raises(StreamAbortedError, match="DRIVE") as aborted:  # the default lead: 0.5 s real at
                table.stream(t, poses)  # 2x (0.1 s underran once, at load 9 on 2 cores, before the drive fault came)
            final = table.wait_for_state("faulted", 10)
            raised = [name for event in faults.drain() for name in event.raised]
            # the rate fitted over the round trips' midpoints: a round trip's asymmetry (up to its 20 ms, under load
            # more) over the ~3 s of real time they span here bounds the error near 1 %
            assert table.clock.stats()["rate"] == pytest.approx(2.0, rel=1e-2)
    finally:
        counters = emulator.stop()
    assert aborted.value.report.underruns == 0 and counters["samples_late"] == 0
    assert "DRIVE" in final.faults and raised == ["DRIVE"]
    np.testing.assert_allclose(final.pose, np.zeros(6), atol=1e-4)  # stopped, then home with the tilt undone
    assert counters["faults_raised"] == {"DRIVE": 1}


# ----- connection ---------------------------------------------------------------------------------------------


def connect_without_a_controller_times_out(url: str, key_file: Path) -> None:
    with pytest.raises(TableTimeoutError, match="no answer from the table controller"):
        open_table(url, key_file=str(key_file), connect_timeout=0.3).connect()


def moves_are_shown_by_the_status(emulator: EmulatorProcess, key_file: Path) -> None:
    """Right after SET_TILT and HOME return, ``status()`` shows the table armed where the move ended, again and
    again (the emulator given a link delay and a clock at 2x, so that answers and statuses race).

    The emulator at 2x needs twice the CPU of real time; on a host loaded beyond its two cores it falls behind its
    clock and answers late (at 5x, once, ARM found no answer in the default 5 × 0.15 s): the commands here wait
    up to 13 × 0.15 s, as in :func:`commands_survive_loss` — what is checked is the status after the answer."""
    try:
        with open_table(emulator.url, key_file=str(key_file), retries=12) as table:
            table.arm()
            for angle in (1.0, -0.5):
                table.set_tilt(math.radians(angle))
                status = table.status()
                assert status.state == "armed" and status.pose[4] == pytest.approx(math.radians(angle), abs=1e-4)
                table.home()
                status = table.status()
                assert status.state == "armed"
                np.testing.assert_allclose(status.pose, np.zeros(6), atol=1e-4)
    finally:
        emulator.stop()
