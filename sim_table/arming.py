"""Whether a host keeps its heartbeat up well enough to arm the table.

Armed, the controller stops the table (HEARTBEAT_LOST) when the host that armed it has sent no signed HEARTBEAT for
``watchdog_ns``. A client that sends heartbeats more slowly than that — a ground station at its default 1 Hz
against the default 1 s watchdog, whose jitter trips it a few seconds into a motion — is refused at the ARM, with its
reason, instead of faulting mid-motion. A commanding client must send a signed HEARTBEAT at least every
``watchdog_ns / 2`` (2 Hz for the default 1 s: one may be lost); the ARM is taken only from a host whose last two signed
heartbeats arrived at most :data:`ARM_GAP` × ``watchdog_ns`` apart, the last one at most that long before the ARM
(the margin between the two fractions leaves room for a busy host's jitter). The rig sends 50 Hz
(``drivers.mavlink.HEARTBEAT_RATE``).
"""

from __future__ import annotations

ARM_GAP = 0.75
"""Longest gap between the heartbeats before an ARM, as a fraction of the watchdog."""

STATUS_TEXT_BYTES = 50
"""Longest MAVLink STATUSTEXT text [bytes] (common.xml)."""


def heartbeat_problem(beats: tuple[int | None, int | None], arm_ns: int, watchdog_ns: int) -> str | None:
    """Why an ARM at ``arm_ns`` from a host whose last two signed heartbeats arrived at ``beats`` (previous, last;
    None: none) is refused — at most :data:`STATUS_TEXT_BYTES` characters, for a STATUSTEXT — or None when the host
    keeps its heartbeat up (module docstring). Times in the watchdog's clock [ns]."""
    period_ns = round(ARM_GAP * watchdog_ns)
    need = f"HEARTBEAT <={min(watchdog_ns / 2e9, 99.99):.2f}s apart"
    previous, last = beats
    if last is None:
        return f"ARM refused: no beat; {need}"
    if previous is None:
        return f"ARM refused: 1 beat only; {need}"
    if last - previous > period_ns or arm_ns - last > period_ns:
        gap = min(max(last - previous, arm_ns - last) / 1e9, 999.99)
        return f"ARM refused: gap {gap:.2f}s; {need}"
    return None
