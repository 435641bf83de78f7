"""Suspenders: the enclosure door (an interlock input of the emulated controller, ``--door-open S:D``) opens during
the first run; the sequence holds before the second until it closes, saying why, and then goes on by itself. The
conditions themselves are tested in-process."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from drivers.controller import TableStatus
from protocols.signing_key import write_signing_key
from rig.emulator import EmulatorProcess, specimen_flags
from rig.orchestrator import Orchestrator, OrchestratorState, Progress
from rig.orchestrator.suspenders import suspensions
from rig.sequence import load_sequence
from rig.session import SessionLog, read_session
from tests.helpers.sequences import TINY


def status(host_ns: int, inputs: tuple[str, ...] = ()) -> TableStatus:
    return TableStatus(0, "armed", 0, 0, 0, (), 0, np.zeros(6), host_ns, inputs=inputs)


def test_the_door_and_a_stale_link_suspend_and_nothing_else_does() -> None:
    assert suspensions(status(1_000_000_000), 1_100_000_000, 0.5) == []
    assert suspensions(status(1_000_000_000, ("door_open",)), 1_000_000_000, 0.5) == ["the enclosure door is open"]
    assert suspensions(status(1_000_000_000), 1_300_000_000, 0.5) == [
        "the table link is poor: no status for 0.30 s (link timeout 0.5 s)"]


@pytest.mark.integration  # starts the emulator
def test_an_open_door_holds_the_sequence_until_it_closes(tmp_path: Path) -> None:
    key_file = tmp_path / "rig.key"
    write_signing_key(key_file)
    path = tmp_path / "door.toml"
    path.write_text(TINY)  # two records: the door holds the second
    sequence = load_sequence(path)
    log = SessionLog.create(tmp_path / "s.h5", rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                            software_version="test")
    # the door opens 1 s after the first stream starts (the lead: at the drive's start) and closes 15 s later in
    # controller time, some 11 s after the first run's drive ends (at rest the emulator's clock is the wall clock's):
    # the host's steps between the runs (the recorder's linger and its wait for the last batches) take far less
    emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", *specimen_flags(sequence.bodies), "--speed", "max",
                                     "--door-open", "1:15", key_file=key_file)
    messages: list[str] = []
    try:
        def seen(progress: Progress) -> None:
            if not messages or messages[-1] != progress.message:
                messages.append(progress.message)

        orchestrator = Orchestrator(sequence, emulator.url, log, table_options={"key_file": str(key_file)},
                                    on_update=seen)
        result: list[OrchestratorState] = []
        worker = threading.Thread(target=lambda: result.append(orchestrator.run()), daemon=True)
        worker.start()
        worker.join(120)
        assert not worker.is_alive()
    finally:
        emulator.stop()
        log.close()
    assert result == [OrchestratorState.DONE]
    first, second = read_session(tmp_path / "s.h5")["runs"]
    assert [first["status"], second["status"]] == ["completed", "completed"]
    interlock = [e["text"] for e in first["events"] if e["text"].startswith("interlock")]
    assert interlock[0] == "interlock inputs: door_open"  # during the first run: a line of its own
    # the door's lines (a busy host may add a poor link's reason to them, or lines of its own)
    door = [e["text"] for e in second["events"] if "door" in e["text"]]
    assert door[0].startswith("suspended: the enclosure door is open")
    assert door[-1].startswith("resumed: cleared (the enclosure door is open")
    assert any(m.startswith("suspended: the enclosure door is open") and m.endswith("the sequence goes on when it "
                                                                                    "clears") for m in messages)
