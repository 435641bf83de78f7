"""Suspenders (Bluesky's idea): conditions that hold the sequence while they are true and let it go on when they
clear, checked before every run and, for what a status reports, during it (``docs/limits.md``).

- the **enclosure door**: an interlock input of the controller (``TableStatus.inputs`` holds ``"door_open"``; the
  emulator's ``--door-open S:D``);
- the **table link's quality**: the latest status is older than :data:`LINK_POOR_FRACTION` of the rig
  configuration's ``link_timeout_s`` (a link that stays silent for the whole timeout is lost, and ends the session);
- an accelerometer **noisier at rest than its sheet's noise floor**: ``rig.orchestrator.noise``.

Each reason is ``CONDITION`` or ``CONDITION: what was measured`` (:func:`conditions`).
"""

from __future__ import annotations

from drivers.controller import TableStatus

LINK_POOR_FRACTION = 0.5
"""A status older than this fraction of the link timeout makes the link poor."""

POLL_SECONDS = 0.1
"""How often a suspended sequence checks its conditions [s]."""


def suspensions(status: TableStatus, now_ns: int, link_timeout_s: float) -> list[str]:
    """Why the sequence must wait now (empty: it need not): ``status`` the latest, ``now_ns`` host monotonic time
    [ns], ``link_timeout_s`` the rig configuration's [s]."""
    reasons = []
    if "door_open" in status.inputs:
        reasons.append("the enclosure door is open")
    age = (now_ns - status.host_ns) * 1e-9
    if age > LINK_POOR_FRACTION * link_timeout_s:
        reasons.append(f"the table link is poor: no status for {age:.2f} s (link timeout {link_timeout_s:g} s)")
    return reasons


def conditions(reasons: list[str]) -> set[str]:
    """The conditions of ``reasons`` without what was measured (the text before the first ``": "``): a hold whose
    numbers change is the same hold."""
    return {reason.split(": ", 1)[0] for reason in reasons}
