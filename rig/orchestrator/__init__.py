"""Test sequences played on the table: the orchestrator, its states, the operator's steps, the run recorder."""

from rig.orchestrator.orchestrator import LEAD, Orchestrator, SessionStoppedError
from rig.orchestrator.sinks import RunSink, SessionSink
from rig.orchestrator.states import (
    FINAL_STATES,
    TRANSITIONS,
    IllegalTransitionError,
    Operator,
    OperatorDeclinedError,
    OrchestratorState,
    Progress,
    Unattended,
)

__all__ = ["FINAL_STATES", "LEAD", "TRANSITIONS", "IllegalTransitionError", "Operator", "OperatorDeclinedError",
           "Orchestrator", "OrchestratorState", "Progress", "RunSink", "SessionSink", "SessionStoppedError",
           "Unattended"]
