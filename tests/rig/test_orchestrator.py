"""The orchestrator against the emulated table (the session's emulator with the sequence's bodies, ``body_table``,
rested between tests; MAVLink over loopback UDP): pause at the end of a record, abort and emergency stop mid-record
(the emulator's counters show them, the run is logged ``aborted``), a run that cannot be played is refused and
logged, resume from the first run that did not complete."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.orchestrator import Orchestrator, OrchestratorState
from rig.sequence import Sequence, load_sequence
from rig.session import SessionLog, read_session, run_needs, space
from tests.helpers.sequences import TINY, new_log, play_on, wait_for
from tests.helpers.tables import SharedTable

BodyTable = Callable[..., SharedTable]
"""The ``body_table`` fixture (``tests/rig/conftest.py``)."""

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)




def test_pause_takes_effect_at_the_end_of_the_record_and_resume_continues(tiny: Sequence, tmp_path: Path,
                                                                         body_table: BodyTable) -> None:
    log = new_log(tiny, tmp_path / "s.h5")
    seen: list[tuple[int, int]] = []

    def during(o: Orchestrator) -> None:
        wait_for(lambda: o.progress.samples_sent > 500)
        o.pause()
        wait_for(lambda: o.state is OrchestratorState.PAUSED)
        seen.append((len(log.runs()), o.progress.runs_done))
        time.sleep(1.0)  # the table holds while paused: nothing starts
        seen.append((len(log.runs()), o.progress.runs_done))
        o.resume()

    state, counters = play_on(body_table(tiny), tiny, log, during)
    log.close()
    assert state is OrchestratorState.DONE
    assert seen == [(1, 1), (1, 1)]  # paused after the first record, which completed; the second not begun
    runs = read_session(tmp_path / "s.h5")["runs"]
    assert [r["status"] for r in runs] == ["completed", "completed"]
    assert counters["streams_completed"] == 2 and counters["stops"] == 0 and counters["watchdog_stops"] == 0


@pytest.mark.parametrize("kind", ["abort", "emergency_stop"])
def test_abort_and_emergency_stop_act_at_once_and_the_run_is_logged_aborted(kind: str, tiny: Sequence,
                                                                           tmp_path: Path,
                                                                           body_table: BodyTable) -> None:
    log = new_log(tiny, tmp_path / "s.h5")
    when: list[float] = []

    def during(o: Orchestrator) -> None:
        wait_for(lambda: o.progress.samples_sent > 1000)
        when.append(time.monotonic())
        getattr(o, kind)()
        wait_for(lambda: o.state in (OrchestratorState.DONE, OrchestratorState.FAULTED))
        when.append(time.monotonic())

    state, counters = play_on(body_table(tiny), tiny, log, during)
    log.close()
    assert state is (OrchestratorState.DONE if kind == "abort" else OrchestratorState.FAULTED)
    runs = read_session(tmp_path / "s.h5")["runs"]
    assert [r["status"] for r in runs] == ["aborted"]  # the second record never started
    assert kind.replace("_", " ") in runs[0]["attrs"]["reason"]
    assert counters["streams_completed"] == 0
    assert counters["stops" if kind == "abort" else "emergency_stops"] == 1
    assert counters["watchdog_stops"] == 0  # left disarmed (abort) or braked (emergency stop), not cut off
    # the table stopped streaming at once: the run's commanded drive is ~5 s, the logged motion ends early
    accel = runs[0]["accel"]["0"]
    assert accel[-1, 0] < runs[0]["commanded"][-1, 0] - 0.5


def test_resume_plays_again_what_did_not_complete(tiny: Sequence, tmp_path: Path, body_table: BodyTable) -> None:
    """An aborted first session is resumed: the aborted run is played again in a new attempt, the rest follow."""
    path = tmp_path / "s.h5"
    log = new_log(tiny, path)

    def abort_early(o: Orchestrator) -> None:
        wait_for(lambda: o.progress.samples_sent > 300)
        o.abort()

    table = body_table(tiny)
    play_on(table, tiny, log, abort_early)
    log.close()
    log = SessionLog.resume(path)
    assert log.done_plan_indices() == set()
    state, counters = play_on(table, tiny, log)  # the table at rest again, as the operator would leave it
    log.close()
    assert state is OrchestratorState.DONE and counters["streams_completed"] == 2
    runs = read_session(path)["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(0, "aborted"), (0, "completed"), (1, "completed")]
    for r in runs[1:]:  # every accelerometer sample over the drive's duration, none missing
        duration = r["commanded"][-1, 0]
        t = r["accel"]["0"][:, 0]
        inside = t[(t >= 0.0) & (t <= duration)]
        assert inside[0] < 1e-3 and inside[-1] > duration - 1e-3
        np.testing.assert_allclose(np.diff(inside), 1e-3, atol=1e-9)
        assert abs(len(inside) - duration * 1000) <= 1


class ScriptedOperator:
    """An operator who answers from a script and notes what was asked."""

    def __init__(self) -> None:
        self.asked: list[str] = []

    def place_bodies(self, prompt: str) -> None:
        self.asked.append(f"place: {prompt}")

    def confirm_run(self, run: Any, description: str) -> None:
        self.asked.append(f"confirm {run.plan_index}: {description}")

    def which_fell(self, run: Any, bodies: Any) -> list[tuple[int, int]]:
        self.asked.append(f"which fell {run.plan_index}")
        return [(bodies[0].body_id, -1)]


def test_the_operator_places_confirms_and_reports_falls_the_sensors_missed(tmp_path: Path,
                                                                           body_table: BodyTable) -> None:
    """A stocky body that stands through a weak record: the sensors report nothing, so the operator is asked which
    bodies fell; the answer is logged with source ``operator``. Placing and confirming are asked in order."""
    text = TINY.replace("confirm_before_run = false", "confirm_before_run = true\nask_detections = true")
    text = text.replace("table5 = 5", "table5 = 3")  # 152 x 500 mm: α = 16.9°
    text = text.replace('window_s = [0.5, 3.5]', 'window_s = [0.0, 0.5]').replace('window_s = [5.0, 8.0]',
                                                                                  'window_s = [0.0, 0.5]')
    path = tmp_path / "ask.toml"
    path.write_text(text)
    sequence = load_sequence(path)
    log = new_log(sequence, tmp_path / "s.h5")
    operator = ScriptedOperator()
    state, counters = play_on(body_table(sequence), sequence, log, operator=operator)
    log.close()
    assert state is OrchestratorState.DONE and counters["overturns"] == []
    kinds = [a.split(":")[0].split(" ")[0] for a in operator.asked]
    assert kinds == ["place", "confirm", "which", "confirm", "which"]
    assert "scale factor" in operator.asked[1]
    for run in read_session(tmp_path / "s.h5")["runs"]:
        assert [(d["body_id"], d["direction"], d["source"]) for d in run["detections"]] == [(1, -1, "operator")]


def _emulator_command_lines() -> dict[str, list[str]]:
    """The command lines of this process's ``python -m sim_table`` children (Linux /proc), by process id."""
    children = []
    for task in Path("/proc/self/task").iterdir():
        children += (task / "children").read_text().split()
    lines = {pid: Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0") for pid in children}
    return {pid: line for pid, line in lines.items() if "sim_table" in line}


def _new_emulator_line(before: dict[str, list[str]]) -> list[str]:
    """The command line of the one emulator started since ``before`` (the session's shared tables are children
    too)."""
    (line,) = [line for pid, line in _emulator_command_lines().items() if pid not in before]
    return line


def test_the_emulated_table_is_the_sequence_s_rig(tmp_path: Path) -> None:
    """``rig run --emulate`` (and the service, and the demo: ``rig.orchestrator.setup.table_for``) starts the
    emulator with the sequence's rig configuration when it is not the default one, written out as TOML that loads
    back to the same table model; with the default rig, no configuration is passed."""
    import math

    from analysis.table.model import TableModel
    from rig.orchestrator.setup import table_for

    (tmp_path / "tiny.toml").write_text(TINY + "\n[rig.limits.surge]\nacceleration_g = 0.4\n")
    custom = load_sequence(tmp_path / "tiny.toml")
    assert custom.table != TableModel()
    before = _emulator_command_lines()
    with table_for(custom, None, True, None, math.inf):
        line = _new_emulator_line(before)
        config = Path(line[line.index("--rig-config") + 1])
        assert TableModel.from_toml(config) == custom.table
    (tmp_path / "plain.toml").write_text(TINY)
    with table_for(load_sequence(tmp_path / "plain.toml"), None, True, None, math.inf):
        line = _new_emulator_line(before)
        assert "--rig-config" not in line


def test_a_run_without_room_on_the_disk_is_not_begun(tiny: Sequence, tmp_path: Path, body_table: BodyTable,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Less free on the session's file system than the first run needs: the session ends ``disk full: …`` before
    that run begins (no run in the file, no drive streamed), the table left at rest."""
    monkeypatch.setattr(space, "free_bytes", lambda where: 1 << 20)  # 1 MiB: less than the reserve alone
    log = new_log(tiny, tmp_path / "s.h5")
    orchestrators: list[Orchestrator] = []
    state, counters = play_on(body_table(tiny), tiny, log, during=orchestrators.append)
    log.close()
    assert state is OrchestratorState.FAULTED
    message = orchestrators[0].progress.message
    drive = tiny.prepare(tiny.plan()[0])
    needed = run_needs(drive.duration, len(drive.t), 1, 1) / (1 << 20)
    assert message.startswith("disk full: ") and (f"run 1 ({drive.duration:.1f} s of drive, 1 accelerometers, 1 "
                                                  f"bodies) needs about {needed:.1f} MiB free") in message, message
    assert read_session(tmp_path / "s.h5")["runs"] == []
    assert counters["streams_completed"] == 0 and counters["state"] in ("idle", "armed")
