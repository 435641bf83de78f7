"""The lab's own mode: real time with a person in the loop (issue 21). The orchestrator against the emulated table
(its own process, MAVLink on loopback): an operator who takes long at a prompt, a table stopped behind the
session's back while it waits, a run whose samples were lost logged ``degraded`` (and left out of Fig. 13), and a
table link lost mid-run ended at once instead of waiting minutes."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest

from analysis.table.link import LinkSettings
from drivers.controller import LINK_GRACE, WAIT_SLICE, open_table
from rig.analyze import analyze_session
from rig.emulator import EmulatorProcess, specimen_flags
from rig.orchestrator import Orchestrator, OrchestratorState
from rig.sequence import Sequence, load_sequence
from rig.session import read_session
from tests.helpers.sequences import TINY, new_log, play, wait_for

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

SLOW_ANSWER = 3.0
"""How long the slow operator takes [s]: three times the controller's default watchdog (1 s), thirty times the
100 ms the table used to allow."""


class SlowOperator:
    """Places the bodies after :data:`SLOW_ANSWER` s; optionally has the table emergency-stopped meanwhile from a
    second connection (a colleague at the console: an observer, which does not claim the table but may stop it)."""

    def __init__(self, url: str | None = None, key: Path | None = None) -> None:
        self.url, self.key = url, key

    def place_bodies(self, prompt: str) -> None:
        if self.url is not None:
            with open_table(self.url, key_file=str(self.key), observe=True) as other:
                other.emergency_stop()
        time.sleep(SLOW_ANSWER)

    def confirm_run(self, run: Any, description: str) -> None:
        pass

    def which_fell(self, run: Any, bodies: Any) -> list[tuple[int, int]]:
        return []


def test_a_slow_answer_at_the_prompt_keeps_the_table_armed_at_1x(tiny: Sequence, tmp_path: Path,
                                                                  key_file: Path) -> None:
    """At real time the link's heartbeats go on while the operator takes 3 s to place the bodies: the runs play."""
    log = new_log(tiny, tmp_path / "s.h5")
    with EmulatorProcess.start("mavlink://127.0.0.1:0", *specimen_flags(tiny.bodies), key_file=key_file) as emulator:
        orchestrator = Orchestrator(tiny, emulator.url, log, table_options={"key_file": str(key_file)},
                                    operator=SlowOperator())
        assert orchestrator.run() is OrchestratorState.DONE, orchestrator.progress.message
        counters = emulator.stop()
    log.close()
    assert [r["status"] for r in read_session(tmp_path / "s.h5")["runs"]] == ["completed", "completed"]
    assert counters["faults_raised"] == {} and counters["watchdog_stops"] == 0


def test_a_table_stopped_while_the_operator_was_asked_ends_the_session_saying_so(
        tiny: Sequence, tmp_path: Path, key_file: Path) -> None:
    log = new_log(tiny, tmp_path / "s.h5")
    with EmulatorProcess.start("mavlink://127.0.0.1:0", "--speed", "max", key_file=key_file) as emulator:
        orchestrator = Orchestrator(tiny, emulator.url, log, table_options={"key_file": str(key_file)},
                                    operator=SlowOperator(emulator.url, key_file))
        assert orchestrator.run() is OrchestratorState.FAULTED
    log.close()
    message = orchestrator.progress.message
    assert "emergency_stopped while waiting for the operator" in message, message
    assert read_session(tmp_path / "s.h5")["runs"] == []  # no run began on a stopped table


def test_a_run_that_lost_samples_is_degraded_and_left_out_of_fig13_unless_asked(
        tiny: Sequence, tmp_path: Path, key_file: Path) -> None:
    """10 % of the datagrams lost both ways: the drive plays through (chunks are sent twice), but accelerometer
    batches are missing, so no run may be logged ``completed``."""
    log = new_log(tiny, tmp_path / "s.h5")
    state, counters = play(tiny, log, key_file, emulator_flags=("--loss", "10"))
    log.close()
    runs = read_session(tmp_path / "s.h5")["runs"]
    assert state is OrchestratorState.DONE and counters["streams_completed"] == 2, (  # both drives played through
        state, [(r["status"], r["attrs"].get("reason"), [e["text"] for e in r["events"]]) for r in runs],
        counters["timing"], counters["link"])
    assert [r["status"] for r in runs] == ["degraded", "degraded"]
    for run in runs:
        why = run["attrs"]["degraded"]
        assert "accelerometer batch(es) lost" in why
        assert any(e["text"].startswith("degraded: ") for e in run["events"])
    left_out = analyze_session(tmp_path / "s.h5", write=False)
    assert left_out.runs == [] and [s.status for s in left_out.skipped] == ["degraded", "degraded"]
    assert "--include-degraded" in left_out.skipped[0].reason
    taken = analyze_session(tmp_path / "s.h5", write=False, include_degraded=True)
    assert len(taken.runs) == 2


def test_a_table_link_lost_mid_run_ends_the_run_interrupted_at_once(tiny: Sequence, tmp_path: Path,
                                                                    key_file: Path) -> None:
    """The emulator killed mid-record: the run is ``interrupted: table link lost`` within the link timeout (not
    after the minutes a stop's settle used to wait)."""
    log = new_log(tiny, tmp_path / "s.h5")
    emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", *specimen_flags(tiny.bodies), key_file=key_file)
    orchestrator = Orchestrator(tiny, emulator.url, log, table_options={"key_file": str(key_file)})
    result: list[OrchestratorState] = []
    worker = threading.Thread(target=lambda: result.append(orchestrator.run()), daemon=True)
    worker.start()
    wait_for(lambda: orchestrator.progress.samples_sent > 500)
    emulator.proc.kill()
    killed = time.monotonic()
    worker.join(60)
    ended = time.monotonic() - killed
    emulator.proc.wait()
    log.close()
    assert result == [OrchestratorState.FAULTED]
    link = LinkSettings()
    # silence, the grace to confirm it, one wait slice, and up to the lead of chunks already due (sent by the
    # clock estimate alone) — plus two seconds for a busy machine: not the 120 s of a stop's settle
    assert ended < link.link_timeout_s + LINK_GRACE + WAIT_SLICE + link.lead_s + 2.0
    assert "table link lost" in orchestrator.progress.message
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    assert run["status"] == "interrupted" and run["attrs"]["reason"].startswith("table link lost")


def test_a_lead_beyond_the_controller_s_buffer_is_refused_before_the_stream(tmp_path: Path,
                                                                           key_file: Path) -> None:
    """The emulator with a 0.5 s buffer, the sequence's rig asking for a 2 s lead: refused before anything streams,
    naming both."""
    text = TINY + "\n[rig.controller]\nlead_s = 2.0\nbuffer_s = 3.0\nwatchdog_s = 2.0\n"
    path = tmp_path / "lead.toml"
    path.write_text(text)
    sequence = load_sequence(path)
    log = new_log(sequence, tmp_path / "s.h5")
    with EmulatorProcess.start("mavlink://127.0.0.1:0", "--speed", "max", "--buffer", "0.5",
                               key_file=key_file) as emulator:
        orchestrator = Orchestrator(sequence, emulator.url, log, table_options={"key_file": str(key_file)})
        assert orchestrator.run() is OrchestratorState.FAULTED
        counters = emulator.stop()
    log.close()
    message = orchestrator.progress.message
    assert "holds 500 setpoint samples (0.5 s)" in message and "lead_s = 2 s" in message, message
    assert counters["streams_started"] == 0 and counters["commands_accepted"] == 0  # not even armed
