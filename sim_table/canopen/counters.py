"""What the CANopen endpoint counts (:mod:`sim_table.canopen.endpoint`), reported at the emulator's exit."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class BusCounters:
    """What the endpoint counted (reported at exit)."""

    syncs: int = 0
    sync_series: int = 0
    sync_delay_max_us: float = 0.0
    """Largest arrival − grid slot of a SYNC [µs, controller time]: how late SYNCs came."""
    sync_handling_max_us: float = 0.0
    """Largest time from a SYNC's arrival to its handling [µs, real time] (the bus thread waiting its turn)."""
    rpdos_lost: int = 0  # injected loss: a latched RPDO replaced by the previous one
    frames_sent: int = 0
    frames_not_sent: int = 0  # injected loss, outbound
    master_heartbeats: int = 0
    chunks_sent: int = 0
    chunks_stalled: int = 0
    feedback_deferred: int = 0
    """SYNCs answered late, when the physics had computed the instant they report (the TPDOs keep their stamp)."""
    answers_dropped: int = 0
    answers_forgotten: int = 0
    """SYNCs handled after the instant they report had left the history
    (:data:`~sim_table.canopen.history.HISTORY`): not answered, so the master counts their samples lost rather than
    being told a later position."""
    accel_samples_sent: int = 0
    emcy_sent: int = 0
    targets_refused: int = 0
    """SYNCs whose six targets had no pose (a leg beyond its stroke, or no forward kinematics): refused unplayed."""
    refusals: int = 0
    """Setpoints the core refused (those and the poses it refused for their values, rates or envelope)."""
    following_errors: int = 0
    """Drives that faulted on a following error beyond their window 0x6065."""
    following_error_max_um: int = 0
    """Largest |following error| [µm] a drive had while it watched it (enabled, the core streaming)."""
    overturn_events: int = 0
    overturn_messages_sent: int = 0
    backlog_waits: int = 0
    """Looks of the tick thread that waited for the receive thread to handle the frames received
    (:mod:`sim_table.canopen.endpoint`)."""
    backlog_wait_max_us: float = 0.0
    """The longest such wait [µs, real time]."""
    backlog_limit_reached: int = 0
    """Waits that ended at :data:`~sim_table.canopen.endpoint.BACKLOG_LIMIT` with frames still unhandled."""
