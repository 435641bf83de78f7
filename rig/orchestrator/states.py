"""The orchestrator's explicit states, its progress report and what the operator is asked."""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from rig.sequence import PlacedBody, PlannedRun


class OrchestratorState(enum.StrEnum):
    """Where a session is (``docs/orchestrator.md``). ``done`` and ``faulted`` are final for one
    :meth:`~rig.orchestrator.Orchestrator.run`; a session file in either can be resumed."""

    IDLE = "idle"
    CONNECTING = "connecting"
    TILTING = "tilting"
    WAITING = "waiting for the operator"
    RUNNING = "running"
    PAUSED = "paused"
    STOPPING = "stopping"
    DONE = "done"
    FAULTED = "faulted"


FINAL_STATES = frozenset({OrchestratorState.DONE, OrchestratorState.FAULTED})

_S = OrchestratorState
_ENDS = frozenset({_S.DONE, _S.FAULTED})

TRANSITIONS: Mapping[OrchestratorState, frozenset[OrchestratorState]] = {
    _S.IDLE: frozenset({_S.CONNECTING}),
    # an empty plan (every run done earlier) goes straight to stopping; an abort before the first move ends it
    _S.CONNECTING: frozenset({_S.TILTING, _S.STOPPING}) | _ENDS,
    _S.TILTING: frozenset({_S.WAITING}) | _ENDS,
    # waiting → waiting: the bodies placed, then the first run confirmed; → tilting/stopping: the runs refused
    _S.WAITING: frozenset({_S.WAITING, _S.RUNNING, _S.PAUSED, _S.TILTING, _S.STOPPING}) | _ENDS,
    _S.RUNNING: frozenset({_S.RUNNING, _S.WAITING, _S.PAUSED, _S.TILTING, _S.STOPPING}) | _ENDS,
    _S.PAUSED: frozenset({_S.RUNNING, _S.WAITING, _S.TILTING, _S.STOPPING}) | _ENDS,
    _S.STOPPING: _ENDS,
    _S.DONE: frozenset(),
    _S.FAULTED: frozenset(),
}
"""The states each state may leave to (``docs/orchestrator.md``, States); checked by
:func:`check_transition` on every change. ``done`` and ``faulted`` are reachable from every state after
``idle`` (an abort, an operator's "no", a table fault) and final."""


class IllegalTransitionError(RuntimeError):
    """The orchestrator tried a state change that :data:`TRANSITIONS` does not allow (a bug, not bad input)."""


def check_transition(old: OrchestratorState, new: OrchestratorState) -> None:
    """Raise :class:`IllegalTransitionError` unless ``old`` may leave to ``new``."""
    if new not in TRANSITIONS[old]:
        allowed = ", ".join(sorted(s.value for s in TRANSITIONS[old])) or "nothing (final)"
        raise IllegalTransitionError(f"orchestrator state {old.value!r} cannot change to {new.value!r}; "
                                     f"it may change to: {allowed}")


@dataclass
class Progress:
    """What an operator's screen or a service's telemetry shows; updated from the orchestrator's thread.

    ``runs_done``/``runs_total`` count plan entries (this invocation's and earlier ones'); ``samples_sent``/
    ``samples_total`` the current run's drive; ``table_state`` and ``buffer_depth`` the table's latest status;
    ``peak_accel`` [m/s²] the largest horizontal plate acceleration measured in the current run (gravity's tilt
    component removed); ``detections`` overturns logged in the current run; ``message`` the last event.
    """

    state: OrchestratorState = OrchestratorState.IDLE
    run: PlannedRun | None = None
    runs_done: int = 0
    runs_total: int = 0
    samples_sent: int = 0
    samples_total: int = 0
    table_state: str = ""
    buffer_depth: int = 0
    peak_accel: float = 0.0
    detections: int = 0
    message: str = ""
    outcomes: dict[int, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        """Plain JSON types (telemetry)."""
        return {"state": self.state.value, "run": None if self.run is None else self.run.to_dict(),
                "runs_done": self.runs_done, "runs_total": self.runs_total, "samples_sent": self.samples_sent,
                "samples_total": self.samples_total, "table_state": self.table_state,
                "buffer_depth": self.buffer_depth, "peak_accel": self.peak_accel, "detections": self.detections,
                "message": self.message, "outcomes": {str(k): v for k, v in self.outcomes.items()}}


class Operator(Protocol):
    """The operator's steps. Each call blocks until answered; raising :class:`OperatorDeclinedError` aborts the
    session at that point (nothing moves after it)."""

    def place_bodies(self, prompt: str) -> None:
        """The table holds the angle: place (or re-place) the bodies, then return."""

    def confirm_run(self, run: PlannedRun, description: str) -> None:
        """The next run is ready (``description``: record, scale factor, duration); return to start it."""

    def which_fell(self, run: PlannedRun, bodies: tuple[PlacedBody, ...]) -> list[tuple[int, int]]:
        """The table's sensors reported no overturn: which bodies fell, as (body_id, direction +1 low side /
        −1 high side); empty when none did."""


class OperatorDeclinedError(Exception):
    """The operator declined a step: the session stops there (resumable)."""


class Unattended:
    """No operator: bodies are taken as placed, runs start at once, no overturns are added by hand."""

    def place_bodies(self, prompt: str) -> None:
        return None

    def confirm_run(self, run: PlannedRun, description: str) -> None:
        return None

    def which_fell(self, run: PlannedRun, bodies: tuple[PlacedBody, ...]) -> list[tuple[int, int]]:
        return []
