"""Test sequences played on the table: the orchestrator, its states, the operator's steps, the run recorder."""

from rig.orchestrator.orchestrator import LEAD, Orchestrator, SessionStoppedError
from rig.orchestrator.states import (
    FINAL_STATES,
    Operator,
    OperatorDeclinedError,
    OrchestratorState,
    Progress,
    Unattended,
)

__all__ = ["FINAL_STATES", "LEAD", "Operator", "OperatorDeclinedError", "Orchestrator", "OrchestratorState", "Progress",
           "SessionStoppedError", "Unattended"]
