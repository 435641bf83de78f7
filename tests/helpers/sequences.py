"""The small sequences the orchestrator, CLI and service tests play, and playing one on an emulated table."""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path
from typing import Any

from rig.emulator import EmulatorProcess, specimen_flags
from rig.orchestrator import FINAL_STATES, TRANSITIONS, Orchestrator, OrchestratorState, Progress
from rig.sequence import Sequence
from rig.session import SessionLog
from tests.helpers.tables import SharedTable


def tiny(run_s: float = 3.0) -> str:
    """A small sequence of two runs at 0°, ``run_s`` [s] of each record (NORTHR/RRS_032 from 0.5 s, KOBE/NIS000
    from 5 s), the paper's Table V body 5 at the plate's centre, no confirmation asked. Longer runs for a test that must
    watch one for a while (a browser that starts, unlocks and looks on before the session ends)."""
    return f"""\
name = "tiny"
angles_deg = [0]
records = [
    {{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, {0.5 + run_s}] }},
    {{ record = "fema-farfield:KOBE/NIS000", window_s = [5.0, {5.0 + run_s}] }},
]

[drive]
corner_hz = 1.0
settle_s = 0.3

[operator]
confirm_before_run = false

[[bodies]]
table5 = 5
x = 0.0
y = 0.0
"""


TINY = tiny()
""":func:`tiny` of 3 s runs, the sequence most tests play."""

TINY_ONE_RUN = TINY.replace('    { record = "fema-farfield:KOBE/NIS000", window_s = [5.0, 8.0] },\n', "")
""":data:`TINY` with its first record only: one run."""


def new_log(sequence: Sequence, path: Path) -> SessionLog:
    return SessionLog.create(path, rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                             software_version="test")


def table_flags(sequence: Sequence) -> tuple[str, ...]:
    """The emulator's options for playing ``sequence``: its bodies in their places, virtual time (the same session
    as at 1x)."""
    return (*specimen_flags(sequence.bodies), "--speed", "max")


def play(sequence: Sequence, log: SessionLog, key_file: Path, during: Any = None,
         operator: Any = None, emulator_flags: tuple[str, ...] = (), listen: str = "mavlink://127.0.0.1:0",
         orchestrator_options: dict[str, Any] | None = None) -> tuple[OrchestratorState, dict[str, Any]]:
    """Run the orchestrator (with ``orchestrator_options``) in a thread against a fresh emulator listening on
    ``listen`` (with ``emulator_flags``); ``during(orchestrator)`` from this thread. For a test that needs its own
    emulator (options of its own: fault injection, door or noisy inputs, a speed); else :func:`play_on`."""
    emulator = EmulatorProcess.start(listen, *table_flags(sequence), *emulator_flags, key_file=key_file)
    try:
        state = _orchestrate(sequence, log, emulator.url, key_file, during, operator, orchestrator_options)
    finally:
        counters = emulator.stop()
    return state, counters


def play_on(table: SharedTable, sequence: Sequence, log: SessionLog, during: Any = None, operator: Any = None,
            orchestrator_options: dict[str, Any] | None = None) -> tuple[OrchestratorState, dict[str, Any]]:
    """:func:`play` on a shared table with the sequence's bodies on the plate (``body_table``,
    ``tests/rig/conftest.py``): the final state and the emulator's counters of this play, the table brought back
    to rest as they are read (a second play on it starts as on a fresh emulator)."""
    assert table.flags == table_flags(sequence), f"the shared table has other bodies: {table.flags}"
    try:
        state = _orchestrate(sequence, log, table.url, table.key_file, during, operator, orchestrator_options)
    finally:
        counters = table.counters()
    return state, counters


def _orchestrate(sequence: Sequence, log: SessionLog, url: str, key_file: Path, during: Any, operator: Any,
                 orchestrator_options: dict[str, Any] | None) -> OrchestratorState:
    states = [OrchestratorState.IDLE]

    def seen(progress: Progress) -> None:
        if progress.state is not states[-1]:
            states.append(progress.state)

    orchestrator = Orchestrator(sequence, url, log, table_options={"key_file": str(key_file)},
                                operator=operator, on_update=seen, **(orchestrator_options or {}))
    result: list[OrchestratorState] = []
    worker = threading.Thread(target=lambda: result.append(orchestrator.run()), daemon=True)
    worker.start()
    if during is not None:
        during(orchestrator)
    worker.join(120)
    assert not worker.is_alive()
    # every state change was one the table of transitions allows (the orchestrator checks it; this shows it)
    assert all(new in TRANSITIONS[old] for old, new in itertools.pairwise(states)), states
    assert states[-1] is result[0] and result[0] in FINAL_STATES
    return result[0]


def wait_for(predicate: Any, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)
