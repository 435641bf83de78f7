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

TINY = """\
name = "tiny"
angles_deg = [0]
records = [
    { record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 3.5] },
    { record = "fema-farfield:KOBE/NIS000", window_s = [5.0, 8.0] },
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

TINY_ONE_RUN = TINY.replace('    { record = "fema-farfield:KOBE/NIS000", window_s = [5.0, 8.0] },\n', "")
""":data:`TINY` with its first record only: one run."""


def new_log(sequence: Sequence, path: Path) -> SessionLog:
    return SessionLog.create(path, rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                             software_version="test")


def play(sequence: Sequence, log: SessionLog, key_file: Path, during: Any = None,
         operator: Any = None, emulator_flags: tuple[str, ...] = (), listen: str = "mavlink://127.0.0.1:0",
         orchestrator_options: dict[str, Any] | None = None) -> tuple[OrchestratorState, dict[str, Any]]:
    """Run the orchestrator (with ``orchestrator_options``) in a thread against a fresh emulator listening on
    ``listen`` (with ``emulator_flags``); ``during(orchestrator)`` from this thread."""
    emulator = EmulatorProcess.start(listen, *specimen_flags(sequence.bodies), "--speed", "max",
                                     *emulator_flags, key_file=key_file)  # virtual time: the same session as at 1x
    try:
        states = [OrchestratorState.IDLE]

        def seen(progress: Progress) -> None:
            if progress.state is not states[-1]:
                states.append(progress.state)

        orchestrator = Orchestrator(sequence, emulator.url, log, table_options={"key_file": str(key_file)},
                                    operator=operator, on_update=seen, **(orchestrator_options or {}))
        result: list[OrchestratorState] = []
        worker = threading.Thread(target=lambda: result.append(orchestrator.run()), daemon=True)
        worker.start()
        if during is not None:
            during(orchestrator)
        worker.join(120)
        assert not worker.is_alive()
    finally:
        counters = emulator.stop()
    # every state change was one the table of transitions allows (the orchestrator checks it; this shows it)
    assert all(new in TRANSITIONS[old] for old, new in itertools.pairwise(states)), states
    assert states[-1] is result[0] and result[0] in FINAL_STATES
    return result[0], counters


def wait_for(predicate: Any, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)
