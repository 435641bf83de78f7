"""The orchestrator's table of state transitions: the documented one, and refused when broken."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rig.orchestrator import (
    FINAL_STATES,
    TRANSITIONS,
    IllegalTransitionError,
    Orchestrator,
    OrchestratorState,
    RunSink,
    SessionSink,
)
from rig.orchestrator.states import check_transition
from rig.sequence import load_sequence
from rig.session import SessionLog

DOCS = Path(__file__).resolve().parents[2] / "docs" / "orchestrator.md"

ONE_RUN = """\
name = "one"
angles_deg = [0]
records = [{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 1.5] }]

[[bodies]]
table5 = 5
x = 0.0
y = 0.0
"""


def documented_transitions() -> dict[OrchestratorState, set[OrchestratorState]]:
    """The "leaves to" column of docs/orchestrator.md's States table (notes in parentheses dropped; "waiting"
    is "waiting for the operator")."""
    by_value = {state.value: state for state in OrchestratorState} | {"waiting": OrchestratorState.WAITING}
    table: dict[OrchestratorState, set[OrchestratorState]] = {}
    section = DOCS.read_text().split("## States", 1)[1].split("\n## ", 1)[0]
    for line in section.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0] in by_value:
            leaves = re.sub(r"\([^)]*\)", "", cells[2])
            names = [name.strip() for name in leaves.split(",")]
            table[by_value[cells[0]]] = {by_value[name] for name in names if name != "—"}
    return table


def test_the_documented_states_table_is_the_checked_one() -> None:
    assert documented_transitions() == {state: set(allowed) for state, allowed in TRANSITIONS.items()}
    assert set(TRANSITIONS) == set(OrchestratorState)
    for state in FINAL_STATES:
        assert not TRANSITIONS[state]
    # every state but idle can end the invocation (abort, operator's "no", table fault)
    for state in set(OrchestratorState) - FINAL_STATES - {OrchestratorState.IDLE}:
        assert TRANSITIONS[state] >= FINAL_STATES


def test_an_illegal_transition_is_refused_with_what_is_allowed() -> None:
    check_transition(OrchestratorState.RUNNING, OrchestratorState.PAUSED)
    with pytest.raises(IllegalTransitionError, match=r"'done' cannot change to 'running'.*nothing \(final\)"):
        check_transition(OrchestratorState.DONE, OrchestratorState.RUNNING)
    with pytest.raises(IllegalTransitionError, match=r"'idle' cannot change to 'running'; it may change to: connect"):
        check_transition(OrchestratorState.IDLE, OrchestratorState.RUNNING)


def test_the_orchestrator_refuses_a_state_change_outside_the_table(tmp_path: Path) -> None:
    (tmp_path / "one.toml").write_text(ONE_RUN)
    sequence = load_sequence(tmp_path / "one.toml")
    with SessionLog.create(tmp_path / "s.h5", rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                           software_version="test") as log:
        assert isinstance(log, SessionSink)
        orchestrator = Orchestrator(sequence, "mavlink://127.0.0.1:9", log)
        with pytest.raises(IllegalTransitionError, match="'idle' cannot change to 'tilting'"):
            orchestrator._set(OrchestratorState.TILTING, "tilting")
        assert orchestrator.state is OrchestratorState.IDLE  # unchanged
        run = log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=[[0.0] * 7],
                            bodies=[], sensors=["0"])
        assert isinstance(run, RunSink)
        run.end("completed")
