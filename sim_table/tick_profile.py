"""Where the emulator's tick time goes: CPU time of the tick thread [ns] split by stage, load-independent.

The tick loop calls :meth:`TickProfile.lap` after each stage with that stage's name: the thread's CPU time since
the previous lap (``time.thread_time_ns``, which a busy host's run queue does not inflate) is held for the stage,
and :meth:`TickProfile.commit` adds what an iteration that ran ticks held to the totals (an iteration that ran none
— virtual time holding for setpoints — is left out, as the tick timing leaves it out). One clock read per lap, a
dozen per batch of ticks: the profile costs well under a microsecond a tick.

Stages (:data:`STAGES`): ``controller`` the controller's state machine ticked in Python, its events and status
snapshots, the host's messages applied (the Python overhead of a tick); ``servo`` the legs' model
(``sim_table.actuators`` or ``sim_table.dynamics``, one numba call a batch); ``plate`` the plate's motion
differentiated and the accelerometers; ``physics`` MuJoCo's steps of the specimens (``mujoco.rollout``);
``impacts`` the bodies' angles read from the steps, the impact model and overturn detection; ``specimens`` the
rest of the specimens' batch (the plate's Hermite path per physics step, the tilt samples); ``transport`` what the
endpoint does in the tick thread (messages taken, statuses, telemetry and answers encoded and sent).
"""

from __future__ import annotations

import time

STAGES = ("controller", "servo", "plate", "physics", "impacts", "specimens", "transport")
"""The stages, in the order of a tick (module docstring)."""


class TickProfile:
    """CPU time [ns] of the calling thread per stage (:data:`STAGES`), accumulated lap by lap."""

    def __init__(self) -> None:
        self.ns = dict.fromkeys(STAGES, 0)
        """CPU time [ns] per stage, committed iterations only."""
        self._held = dict.fromkeys(STAGES, 0)
        self._last = time.thread_time_ns()

    def start(self) -> None:
        """Start an iteration: what ran since the last lap belongs to no stage, and nothing is held."""
        for stage in self._held:
            self._held[stage] = 0
        self._last = time.thread_time_ns()

    def lap(self, stage: str) -> None:
        """The CPU time since the last lap (or :meth:`start`) was spent in ``stage``."""
        now = time.thread_time_ns()
        self._held[stage] += now - self._last
        self._last = now

    def commit(self) -> None:
        """Add the iteration's laps to :attr:`ns` (an iteration that ran ticks)."""
        for stage, ns in self._held.items():
            self.ns[stage] += ns

    def clear(self) -> None:
        """Forget the CPU time accumulated so far (:attr:`ns` all zero)."""
        self.ns = dict.fromkeys(STAGES, 0)

    def per_tick_us(self, ticks: int) -> dict[str, float]:
        """Each stage's CPU time per tick [µs] over ``ticks`` ticks, and their ``total``."""
        scale = 1e-3 / max(ticks, 1)
        stages = {stage: ns * scale for stage, ns in self.ns.items()}
        return {**stages, "total": sum(stages.values())}
