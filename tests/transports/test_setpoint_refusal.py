"""Issue 42, item 1, per transport: a setpoint the table must not play (NaN, inf, 3.4e38, outside the envelope or a
leg's stroke, a step beyond the leg speed) sent straight to the emulator — signed, past the host's own checks — is
refused with a reason the host receives, the table stops and the emulator lives on and answers; and the host refuses
to stream such a trajectory. MAVLink and zenoh: the emulator a separate process (the session's shared one:
``tests/helpers/tables.py``), real sockets. CANopen: master and emulator in this process on python-can's ``virtual``
bus."""

from __future__ import annotations

import contextlib
import math
import secrets
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from analysis.table.model import TABLE_IV, AxisLimits, TableLimits, TableModel
from drivers.canopen import CanopenTable
from drivers.controller import FaultSource, SetpointError, TableController, TableError, open_table
from protocols.canopen import od as drive_od
from protocols.mavlink import dialect
from protocols.zenoh.table import SetpointChunk, encode_setpoints
from sim_table.process import Emulator, EmulatorConfig
from tests.helpers.tables import SharedTable

MS = 1_000_000
WAIT = 10.0
"""The longest wait [s] for the table to show what it did (a loaded machine; it normally takes milliseconds)."""


def hostile(case: str) -> np.ndarray:
    """Eight 1 ms samples at home, sample 3 (or the step to it) made hostile."""
    samples = np.zeros((8, 6))
    if case == "nan":
        samples[3, 2] = math.nan
    elif case == "inf":
        samples[3, 2] = math.inf
    elif case == "float32 max":
        samples[3, 2] = 3.4e38
    elif case == "envelope":
        samples[3, 2] = 0.3
    elif case == "rate":
        samples[3:, 0] = 0.01  # 10 mm in 1 ms
    return samples


CASES = {"nan": "heave nan is not a finite number", "inf": "heave inf is not a finite number",
         "float32 max": "heave 3.4e+38 m outside [-0.1800, 0.1800] m",
         "envelope": "heave 0.3 m outside [-0.1800, 0.1800] m",
         "rate": "beyond its speed 0.9000 m/s"}


def send_raw(table: Any, transport: str, seq: int, t_start_ns: int, samples: np.ndarray) -> None:
    """Send ``samples`` as setpoint chunk ``seq``, signed by the driver's link but built here, past every check of the
    host (the protocols' own encoders refuse non-finite values)."""
    if transport == "mavlink":
        flat = [float(v) for v in samples.ravel()] + [0.0] * (48 - samples.size)
        table._send(dialect().MAVLink_shaketable_setpoint_chunk_message(seq, t_start_ns, MS, len(samples), 0, flat))
    else:
        payload = encode_setpoints(SetpointChunk(seq, t_start_ns, MS, np.zeros_like(samples), False))
        table._send_chunk(payload[:-samples.size * 8] + samples.astype("<f8").tobytes())


@pytest.mark.integration  # starts the emulator's process, opens sockets
@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_a_signed_hostile_chunk_is_refused_with_a_reason_the_table_stops_and_the_emulator_answers(
        transport: str, shared_table: SharedTable) -> None:
    emulator, key_file = shared_table.emulator, shared_table.key_file
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            for k, (case, detail) in enumerate(CASES.items()):
                table.arm()
                seq = table._next_seq
                table._next_seq += 1
                table._command("start_stream", (float(seq), 0.0))
                send_raw(table, transport, seq, table.clock.to_controller(time.monotonic_ns()) + 300 * MS,
                         hostile(case))
                stopped = table.wait_for_status(lambda s: s.state == "faulted", WAIT)
                assert "SETPOINT_REFUSED" in stopped.faults, case
                assert table.wait(lambda k=k: len(table.refusals) > k, WAIT), case
                refusal = table.refusals[k]
                assert refusal.seq == seq and refusal.reason.startswith(f"chunk {seq} sample 3: "), refusal
                assert detail in refusal.reason, refusal
                assert np.isfinite(stopped.pose).all() and np.abs(stopped.pose[:3]).max() < 1e-3  # never moved
                assert emulator.exit_code is None
            table.arm()  # the controller answers, armed again
            assert table.status().state == "armed" and not table.status().faults
            t = np.arange(8) * 1e-3
            with pytest.raises(SetpointError, match=r"trajectory not sent: sample 3 \(t = 0\.003 s\): heave nan"):
                table.stream(t, hostile("nan"))
            assert table.status().state == "armed" and len(table.refusals) == len(CASES)  # nothing was sent
    finally:
        counters = shared_table.counters()  # the emulator lives on: it answers
    assert counters["chunks_refused"] == len(CASES) and counters["streams_started"] == len(CASES)
    assert counters["link"]["refusals_sent"] == len(CASES)


# ----- CANopen: the leg drives' targets ---------------------------------------------------------------------------

CANOPEN_RATE = 100
"""SYNC rate [Hz]: master and emulator share this interpreter (``test_canopen_table.py``, ``RATE``)."""
ALLOWANCE_S = 1.0
"""Watchdogs, consumer time and link timeout [s]: a loaded machine may hold a thread of this process that long."""


@contextlib.contextmanager
def canopen_pair() -> Iterator[tuple[Emulator, CanopenTable, threading.Thread]]:
    """The emulator's loop in a thread on a fresh virtual channel and the master connected to it."""
    channel = f"refuse-{uuid.uuid4().hex}"
    emulator = Emulator(EmulatorConfig(listen=f"canopen://{channel}?interface=virtual&target_delay=0.5",
                                       key=secrets.token_bytes(32), watchdog=ALLOWANCE_S))
    stop = threading.Event()
    thread = threading.Thread(target=emulator.run, args=(stop,), name="emulator", daemon=True)
    thread.start()
    table = open_table(emulator.url, rate=CANOPEN_RATE, consumer_time=ALLOWANCE_S)
    table.link_timeout = ALLOWANCE_S
    try:
        table.connect()
        yield emulator, table, thread
    finally:
        table.close()
        stop.set()
        thread.join(timeout=10)
        emulator.close()


def targets_of(table: CanopenTable, pose: np.ndarray) -> list[int]:
    """Each leg's target [its drive's units] for ``pose``, unclipped."""
    lengths = table.table.leg_lengths(pose).tolist()
    return [link.scaling.position(length, leg)
            for leg, (link, length) in enumerate(zip(table._drives, lengths, strict=True), start=1)]


CANOPEN_CASES: dict[str, tuple[Callable[[CanopenTable], list[int]], str]] = {
    "stroke": (lambda table: [table._drives[0].scaling.stroke + 10**6, *targets_of(table, np.zeros(6))[1:]],
               "leg 1 target 3.850000 m outside its stroke [1.6000, 2.8500] m"),
    "envelope": (lambda table: targets_of(table, np.array([0.3, 0, 0, 0, 0, 0])), "surge 0.3 m outside"),
    "rate": (lambda table: targets_of(table, np.array([0, 0, 0.03, 0, 0, 0])), "from the sample before, beyond"),
}


@pytest.mark.parametrize("case", CANOPEN_CASES)
def test_canopen_drives_refuse_targets_the_table_must_not_play(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    make, detail = CANOPEN_CASES[case]
    with canopen_pair() as (emulator, table, thread):
        table.arm()
        faults = table.faults()
        monkeypatch.setattr(table, "_targets", lambda pose: make(table))  # past the master's clipping
        with contextlib.suppress(TableError):  # a move: the master sends targets of its reference, here hostile
            table.set_tilt(math.radians(0.5))
        stopped = table.wait_for_status(lambda s: s.state == "faulted", WAIT)
        monkeypatch.undo()
        assert "SETPOINT_REFUSED" in stopped.faults
        events = faults.drain()
        faults.close()
        sources = {source for event in events for source in event.sources}
        assert FaultSource(1, drive_od.EMCY_REFERENCE_LIMIT) in sources  # the drives said why: reference limit
        counters = emulator.core.counters
        assert counters.chunks_refused >= 1 and detail in counters.last_refusal, counters.last_refusal
        assert thread.is_alive()
        table.arm()  # the drives answer: enabled again at the pose they hold
        assert table.status().state == "armed" and not table.status().faults


def test_the_canopen_master_refuses_to_stream_such_a_trajectory() -> None:
    with canopen_pair() as (_, table, _thread):
        table.arm()
        t = np.arange(8) * 1e-3
        with pytest.raises(SetpointError, match=r"trajectory not sent: sample 3 \(t = 0\.003 s\): heave 0\.3 m"):
            table.stream(t, hostile("envelope"))
        assert table.status().state == "armed"


def test_the_mavlink_and_zenoh_hosts_check_against_the_rig_they_are_given() -> None:
    bigger = TableModel(limits=TableLimits(surge=TABLE_IV.surge, lateral=TABLE_IV.lateral,
                                           heave=AxisLimits(0.35, 0.3, 0.7 * 9.81)))
    for url in ("mavlink://127.0.0.1:1", "zenoh://127.0.0.1:1/table"):
        table: TableController = open_table(url, table=bigger)
        assert table.table is bigger  # not connected: nothing opened
        assert open_table(url).table == TableModel()
