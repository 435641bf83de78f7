"""The operator of an **attended** service session: the orchestrator's steps (place the bodies, confirm a run, which
bodies fell) become prompts in the service's status, answered by the service's signed ``answer`` command (the
console's prompt box).

A prompt is ``{"id": n, "kind": "place_bodies" | "confirm_run" | "which_fell", "text": str, "bodies": [{"body_id",
"name"}, …]}`` (``bodies`` for ``which_fell``). An answer names the prompt's ``id`` (an answer to an older prompt is
refused: the operator saw another question) and is ``"done"`` (the bodies are placed, the run may start; for
``which_fell`` with ``fell``: ``[[body_id, direction], …]``, direction +1 low side / −1 high side) or ``"decline"``
(the session stops there, resumable). An abort or emergency stop while a prompt waits ends the wait; the
orchestrator then stops as it would between steps.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rig.orchestrator import OperatorDeclinedError
from rig.sequence import PlacedBody, PlannedRun

PROMPT_KINDS = ("place_bodies", "confirm_run", "which_fell")
"""The orchestrator's steps (``rig.orchestrator.Operator``)."""

REPLIES = ("done", "decline")
"""What an answer says."""


class AnswerRefusedError(ValueError):
    """An answer that does not fit the waiting prompt (none waiting, another prompt's id, bad ``fell``)."""


class RemoteOperator:
    """``rig.orchestrator.Operator`` answered from another thread (module docstring); ``on_change()`` is called when
    a prompt appears or goes."""

    def __init__(self, on_change: Callable[[], None] = lambda: None) -> None:
        self._on_change = on_change
        self._cond = threading.Condition()
        self._prompt: dict[str, Any] | None = None
        self._answer: tuple[str, list[tuple[int, int]]] | None = None
        self._cancelled = False
        self._count = 0

    @property
    def prompt(self) -> dict[str, Any] | None:
        """The prompt waiting for an answer (a copy), or None."""
        with self._cond:
            return None if self._prompt is None else {**self._prompt, "bodies": list(self._prompt["bodies"])}

    # ----- the orchestrator's side ----------------------------------------------------------------------

    def place_bodies(self, prompt: str) -> None:
        self._ask("place_bodies", prompt, ())

    def confirm_run(self, run: PlannedRun, description: str) -> None:
        self._ask("confirm_run", f"run {run.plan_index + 1} is ready: {description}", ())

    def which_fell(self, run: PlannedRun, bodies: tuple[PlacedBody, ...]) -> list[tuple[int, int]]:
        return self._ask("which_fell", f"run {run.plan_index + 1}: the table's sensors reported no overturn; "
                                       "which bodies fell?", bodies)

    def _ask(self, kind: str, text: str, bodies: tuple[PlacedBody, ...]) -> list[tuple[int, int]]:
        with self._cond:
            if self._cancelled:
                return []
            self._count += 1
            self._prompt = {"id": self._count, "kind": kind, "text": text,
                            "bodies": [{"body_id": b.body_id, "name": b.name} for b in bodies]}
            self._answer = None
        self._on_change()
        try:
            with self._cond:
                while self._answer is None and not self._cancelled:
                    self._cond.wait()
                answer, self._prompt = self._answer, None
        finally:
            self._on_change()
        if answer is None:  # cancelled by a stop: the orchestrator checks its stop request next
            return []
        reply, fell = answer
        if reply == "decline":
            raise OperatorDeclinedError(f"{kind.replace('_', ' ')} declined from the console or a service client")
        return fell

    # ----- the service's side ---------------------------------------------------------------------------

    def answer(self, prompt_id: object, reply: object, fell: object = None) -> str:
        """Answer the waiting prompt ``prompt_id`` (module docstring); what was done, for the reply.
        :class:`AnswerRefusedError` when it does not fit."""
        if reply not in REPLIES:
            raise AnswerRefusedError(f"reply must be one of {', '.join(REPLIES)}, got {reply!r}")
        with self._cond:
            prompt = self._prompt
            if prompt is None or self._answer is not None:
                raise AnswerRefusedError("no prompt is waiting for an answer")
            if isinstance(prompt_id, bool) or prompt_id != prompt["id"]:
                raise AnswerRefusedError(f"prompt {prompt_id!r} is not the one waiting (prompt {prompt['id']}: "
                                         f"{prompt['kind']})")
            bodies = {b["body_id"] for b in prompt["bodies"]}
            overturns = _overturns(fell, bodies) if prompt["kind"] == "which_fell" and reply == "done" else []
            if fell and prompt["kind"] != "which_fell":
                raise AnswerRefusedError(f"fell is only an answer to 'which_fell', not to {prompt['kind']!r}")
            self._answer = (str(reply), overturns)
            self._cond.notify_all()
        return f"prompt {prompt_id} ({prompt['kind']}) answered: {reply}"

    def cancel(self) -> None:
        """A stop: the waiting prompt (and every later one) returns at once."""
        with self._cond:
            self._cancelled = True
            self._cond.notify_all()


def _overturns(fell: object, bodies: set[int]) -> list[tuple[int, int]]:
    """``fell`` checked: a list of ``[body_id, direction]``, a body of the prompt once each, direction ±1."""
    if fell is None:
        return []
    if not isinstance(fell, list) or len(fell) > len(bodies):
        raise AnswerRefusedError(f"fell must be a list of at most {len(bodies)} [body_id, direction] pairs")
    out: list[tuple[int, int]] = []
    for item in fell:
        if not (isinstance(item, list) and len(item) == 2 and all(type(v) is int for v in item)):
            raise AnswerRefusedError(f"fell: each item must be [body_id, direction] (integers), got {item!r}")
        body_id, direction = item
        if body_id not in bodies or direction not in (-1, 1) or any(b == body_id for b, _ in out):
            raise AnswerRefusedError(f"fell: [{body_id}, {direction}]: expected a body of this prompt "
                                     f"({sorted(bodies)}) once, direction +1 (low side) or -1 (high side)")
        out.append((body_id, direction))
    return out
