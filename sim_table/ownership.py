"""Who the table belongs to: one host at a time (``docs/table-controller.md``, One host at a time).

A host **claims** the table with a signed CLAIM at connect; the claim is granted when the table has no owner, when
its owner has been silent for longer than ``timeout_ns`` (no signed heartbeat or command from it: it is gone), or
when the claimant already owns it; otherwise it is refused and the claimant is told who owns the table and since
when. The owner's signed heartbeats and commands keep the claim; its signed RELEASE (on close) ends it. While a
host owns the table, the endpoints refuse motion commands and setpoint chunks from every other host; STOP, DISARM
and EMERGENCY_STOP stay open to anyone (safety). A signed motion command from a host while the table has no live
owner claims it as CLAIM would (a host that arms without claiming first).

The transport decides what identifies a host (MAVLink: address, system and component; zenoh: the signing sender
id) and how it is described to a refused claimant; this module only keeps the owner. Times: ``now_ns`` host
monotonic [ns] (silence), ``since_unix_s`` the controller's wall clock [s since the Unix epoch] when the claim was
granted (what the refused host is told).
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass

OWNER_TIMEOUT = 3.0
"""An owner silent this long [s, real time] loses its claim (zenoh; MAVLink uses its peer timeout, the same)."""


@dataclass(frozen=True)
class Owner:
    """The host that owns the table: its transport identity ``who``, its description (``127.0.0.1:41234 (system
    255, component 190)``), the wall-clock time it claimed the table [s since the Unix epoch] and the host monotonic
    time [ns] it was last heard."""

    who: Hashable
    description: str
    since_unix_s: float
    last_heard_ns: int


class Ownership:
    """The table's owner (module docstring); ``timeout_ns`` [ns] the silence after which an owner is gone."""

    def __init__(self, timeout_ns: int) -> None:
        if timeout_ns <= 0:
            raise ValueError(f"timeout_ns must be > 0 ns, got {timeout_ns!r}")
        self.timeout_ns = int(timeout_ns)
        self._owner: Owner | None = None
        self.claims_granted = 0
        """Claims that made a host the owner (an owner's renewals are not counted)."""
        self.claims_refused = 0
        self.takeovers = 0
        """Claims granted over an owner that had fallen silent."""

    def owner(self, now_ns: int) -> Owner | None:
        """The live owner at ``now_ns``: None when there is none or it has been silent longer than the timeout."""
        owner = self._owner
        if owner is None or now_ns - owner.last_heard_ns > self.timeout_ns:
            return None
        return owner

    def claim(self, who: Hashable, description: str, now_ns: int, now_unix_s: float) -> Owner | None:
        """``who`` (described as ``description``) claims the table at ``now_ns``: None when granted (it owns the
        table; its original time is kept when it owned it already), else the live owner that holds it."""
        held = self.owner(now_ns)
        if held is not None and held.who != who:
            self.claims_refused += 1
            return held
        if held is None and self._owner is not None and self._owner.who != who:
            self.takeovers += 1
        if held is None:
            self.claims_granted += 1
        since = held.since_unix_s if held is not None else now_unix_s
        self._owner = Owner(who, description, since, now_ns)
        return None

    def heard(self, who: Hashable, now_ns: int) -> bool:
        """A signed message of ``who`` arrived at ``now_ns``: keeps its claim if it owns the table; whether it
        does."""
        owner = self.owner(now_ns)
        if owner is None or owner.who != who:
            return False
        self._owner = Owner(owner.who, owner.description, owner.since_unix_s, now_ns)
        return True

    def allows(self, who: Hashable, now_ns: int) -> bool:
        """Whether ``who`` may command motion or send setpoints at ``now_ns``: it owns the table (and is heard), or
        nobody does (the command then claims it: :meth:`claim`)."""
        owner = self.owner(now_ns)
        return owner is None or owner.who == who

    def release(self, who: Hashable, now_ns: int) -> bool:
        """``who`` gives the table up at ``now_ns``: whether it may (it owned it, or nobody did); another host's
        claim is left alone."""
        owner = self.owner(now_ns)
        if owner is not None and owner.who != who:
            return False
        self._owner = None
        return True
