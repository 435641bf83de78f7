"""Suspenders: the enclosure door (an interlock input of the emulated controller, ``--door-open S:D``) opens during
the first run, or an accelerometer turns noisy (``--accel-noisy ID@S:D``); the sequence holds before the second
until it clears, saying why, and then goes on by itself. The conditions themselves are tested in-process."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from analysis.table.configuration import read_configuration
from analysis.table.sensors import SensorSheets
from drivers.controller import AccelBatch, TableStatus
from drivers.hub import Feedback
from protocols.signing_key import write_signing_key
from rig.emulator import EmulatorProcess, specimen_flags
from rig.orchestrator import Orchestrator, OrchestratorState, Progress
from rig.orchestrator.noise import WINDOW_S, NoiseWatch, axis_rms
from rig.orchestrator.suspenders import conditions, suspensions
from rig.sequence import load_sequence
from rig.session import SessionLog, read_session
from tests.helpers.sensor_sheets import accelerometer, sensors_toml, write_rig
from tests.helpers.sequences import TINY

RIG = sensors_toml(accelerometer(0, noise_floor_m_s2=0.05))
"""Accelerometer 0, watched at rest: its noise floor 0.05 m/s² RMS."""


def status(host_ns: int, inputs: tuple[str, ...] = ()) -> TableStatus:
    return TableStatus(0, "armed", 0, 0, 0, (), 0, np.zeros(6), host_ns, inputs=inputs)


def test_the_door_and_a_stale_link_suspend_and_nothing_else_does() -> None:
    assert suspensions(status(1_000_000_000), 1_100_000_000, 0.5) == []
    assert suspensions(status(1_000_000_000, ("door_open",)), 1_000_000_000, 0.5) == ["the enclosure door is open"]
    assert suspensions(status(1_000_000_000), 1_300_000_000, 0.5) == [
        "the table link is poor: no status for 0.30 s (link timeout 0.5 s)"]


def test_a_changed_measure_is_the_same_hold() -> None:
    assert conditions(["the table link is poor: no status for 0.30 s", "the enclosure door is open"]) == {
        "the table link is poor", "the enclosure door is open"}


def test_the_rms_is_taken_about_the_mean() -> None:
    samples = np.array([[0.0, 1.0, 9.0], [0.0, -1.0, 11.0]] * 50)
    assert axis_rms(samples) == pytest.approx([0.0, 1.0, 1.0])


def _sheets(tmp_path: Path) -> SensorSheets:
    return read_configuration(write_rig(tmp_path, RIG)).sensors


class _Table:
    """What the noise watch needs of a table: its accelerometer batches."""

    def __init__(self) -> None:
        self.feedback = Feedback()

    def accelerations(self) -> object:
        return self.feedback.subscribe("accel")

    def send(self, seq: int, sigma: float, rng: np.random.Generator) -> None:
        """A batch of 100 samples at 1 kHz, gravity on z and noise of σ ``sigma`` [m/s²]."""
        samples = np.array([0.0, 0.0, 9.81]) + rng.normal(0.0, sigma, (100, 3))
        self.feedback.publish_accel(AccelBatch(0, seq, seq * 100_000_000, 1_000_000, samples))


def test_a_sensor_noisier_than_its_floor_holds_and_clears_over_the_latest_window(tmp_path: Path) -> None:
    table, rng = _Table(), np.random.default_rng(38)
    with NoiseWatch(table, _sheets(tmp_path)) as watch:
        batches = int(WINDOW_S * 10)
        for seq in range(batches):
            table.send(seq, 0.2, rng)
        reasons = watch.reasons()
        assert len(reasons) == 1 and reasons[0].startswith("accelerometer 0 is noisy at rest: ")
        assert reasons[0].endswith("m/s² RMS, above its sheet's noise floor 0.05 m/s²")
        assert float(reasons[0].split(" reads ")[1].split()[0]) == pytest.approx(0.2, rel=0.2)
        for seq in range(batches, 2 * batches - 1):  # quiet, but the window still holds one noisy batch
            table.send(seq, 0.01, rng)
        assert watch.reasons() != []
        table.send(2 * batches - 1, 0.01, rng)
        assert watch.reasons() == [] and watch.silent == []
    assert not table.feedback._subscribers["accel"]  # unsubscribed on exit


def test_a_sensor_that_sends_nothing_is_not_judged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("rig.orchestrator.noise.WAIT_S", 0.05)
    table = _Table()
    with NoiseWatch(table, _sheets(tmp_path)) as watch:
        assert watch.reasons() == [] and watch.silent == [0]


def test_a_sheet_without_a_noise_floor_is_not_watched(tmp_path: Path) -> None:
    path = write_rig(tmp_path, sensors_toml(accelerometer(0, noise_floor_m_s2=None)))
    table = _Table()
    with NoiseWatch(table, read_configuration(path).sensors) as watch:
        assert watch.reasons() == []
    assert not table.feedback._subscribers["accel"]


def _play_suspended(tmp_path: Path, sequence_text: str, *flags: str) -> tuple[list[dict[str, Any]], list[str]]:
    """Play ``sequence_text`` on an emulator started with ``flags`` (virtual time); the runs read back and the
    orchestrator's messages."""
    key_file = tmp_path / "rig.key"
    write_signing_key(key_file)
    path = tmp_path / "suspended.toml"
    path.write_text(sequence_text)
    sequence = load_sequence(path)
    log = SessionLog.create(tmp_path / "s.h5", rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                            software_version="test")
    emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", *specimen_flags(sequence.bodies), "--speed", "max",
                                     *flags, key_file=key_file)
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
    runs: list[dict[str, Any]] = read_session(tmp_path / "s.h5")["runs"]
    assert [run["status"] for run in runs] == ["completed", "completed"]
    return runs, messages


@pytest.mark.integration  # starts the emulator
def test_an_open_door_holds_the_sequence_until_it_closes(tmp_path: Path) -> None:
    # the door opens 1 s after the first stream starts (the lead: at the drive's start) and closes 15 s later in
    # controller time, some 11 s after the first run's drive ends (at rest the emulator's clock is the wall clock's):
    # the host's steps between the runs (the recorder's linger and its wait for the last batches) take far less
    (first, second), messages = _play_suspended(tmp_path, TINY, "--door-open", "1:15")  # the door holds the second
    interlock = [e["text"] for e in first["events"] if e["text"].startswith("interlock")]
    assert interlock[0] == "interlock inputs: door_open"  # during the first run: a line of its own
    # the door's lines (a busy host may add a poor link's reason to them, or lines of its own)
    door = [e["text"] for e in second["events"] if "door" in e["text"]]
    assert door[0].startswith("suspended: the enclosure door is open")
    assert door[-1].startswith("resumed: cleared (the enclosure door is open")
    assert any(m.startswith("suspended: the enclosure door is open") and m.endswith("the sequence goes on when it "
                                                                                    "clears") for m in messages)


@pytest.mark.integration  # starts the emulator
def test_a_noisy_accelerometer_holds_the_sequence_until_it_is_quiet(tmp_path: Path) -> None:
    write_rig(tmp_path, RIG)  # accelerometer 0's floor 0.05 m/s² RMS; the emulator's noise 0.02
    # accelerometer 0 turns noisy 1 s after the first stream starts and quiet 15 s later (as the door above)
    (first, second), messages = _play_suspended(tmp_path, TINY + '\n[rig]\nconfig = "rig.toml"\n',
                                                "--accel-noisy", "0@1:15")
    assert not [e for e in first["events"] if "noisy" in e["text"]]  # quiet before the first run
    noisy = [e["text"] for e in second["events"] if "noisy" in e["text"]]
    assert noisy[0].startswith("suspended: accelerometer 0 is noisy at rest: ")
    assert "above its sheet's noise floor 0.05 m/s²" in noisy[0]
    assert noisy[-1].startswith("resumed: cleared (accelerometer 0 is noisy at rest")
    held = [m for m in messages if m.startswith("suspended: accelerometer 0 is noisy at rest")]
    assert held and held[0].endswith("the sequence goes on when it clears")
