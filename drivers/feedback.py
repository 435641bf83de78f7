"""What a table controller reports: its status, accelerometer and tilt batches, overturn detections, fault events
and setpoint refusals, and what a stream did (:class:`StreamReport`).

Units and conventions (docs/architecture.md §2): SI; a pose is ``(surge, sway, heave [m], roll, pitch,
yaw [rad])`` as in ``analysis.table.model``; time stamps are integer nanoseconds of **controller time** (the
controller's own monotonic clock) unless a name says ``host``. Overturn direction +1 is towards the low side, −1
towards the high side. Published through :mod:`drivers.hub`; :mod:`drivers.controller` re-exports them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


@dataclass(frozen=True, eq=False)
class TableStatus:
    """One status report of the controller.

    ``t_ns`` controller time [ns]; ``state`` one of ``idle``, ``armed``, ``homing``, ``tilting``, ``streaming``,
    ``stopping``, ``faulted``, ``emergency_stopped`` (``docs/table-controller.md``); ``buffer_depth`` setpoint
    samples buffered and not yet played; ``last_chunk_seq`` the last setpoint chunk accepted; ``underruns`` dry
    spells of the setpoint buffer since power-up; ``faults`` names of the latched fault bits (e.g. ``"STREAM_SILENT"``);
    ``refused_commands`` commands and chunks refused for their signature since power-up; ``pose`` (6,) the
    achieved (measured) pose; ``host_ns`` host monotonic time [ns] the report arrived; ``buffer_capacity`` the
    setpoint samples the controller's buffer holds (0: not reported); ``samples_late`` setpoint samples that
    arrived after they were due and were skipped, since power-up; ``virtual_watchdog_s`` 0 when the controller
    keeps real time, else it runs in virtual time (an emulator at ``--speed max``) and this is its own link
    watchdog [s, host time], the silence :meth:`TableController.check_link` allows it; ``inputs`` the interlock
    inputs set now (``"door_open"``: the enclosure door; empty where the controller reports none);
    ``following_error`` (6,) each leg's commanded minus measured length [m], legs 1…6 (None: not reported).
    """

    t_ns: int
    state: str
    buffer_depth: int
    last_chunk_seq: int
    underruns: int
    faults: tuple[str, ...]
    refused_commands: int
    pose: np.ndarray
    host_ns: int
    buffer_capacity: int = 0
    samples_late: int = 0
    virtual_watchdog_s: float = 0.0
    inputs: tuple[str, ...] = ()
    following_error: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class AccelBatch:
    """Consecutive samples of one plate accelerometer: row k of ``samples`` (n, 3) [m/s², plate frame once
    published — :meth:`drivers.hub.Feedback.mount` turns a sensor mounted off the plate's axes from its own —,
    specific force incl. gravity] was taken at ``t_start_ns + k * spacing_ns`` [ns, controller time]; ``seq`` counts the
    sensor's batches (a gap is a lost batch)."""

    sensor_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray

    def times_ns(self) -> np.ndarray:
        """Time of every sample [ns, controller time], int64."""
        return self.t_start_ns + self.spacing_ns * np.arange(len(self.samples), dtype=np.int64)


@dataclass(frozen=True, eq=False)
class TiltBatch:
    """Consecutive samples of one body's rocking angle from its tilt sensor (the overturn detector's channel):
    ``angles[k]`` [rad] was taken at ``t_start_ns + k * spacing_ns`` [ns, controller time]. The angle is the
    body's rotation about the plate's y axis relative to the plate, > 0 when its top has moved towards +x (the
    low side, downhill). ``body_id`` is its place in the run's bodies (as :class:`Detection`); ``seq`` counts the
    body's batches (a gap is a lost batch)."""

    body_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    angles: np.ndarray

    def times_ns(self) -> np.ndarray:
        """Time of every sample [ns, controller time], int64."""
        return self.t_start_ns + self.spacing_ns * np.arange(len(self.angles), dtype=np.int64)


@dataclass(frozen=True)
class Detection:
    """An overturn on the plate: ``event_id`` (unique per controller run), ``body_id`` (its place in the run's
    bodies), ``direction`` (+1 low side, −1 high side), plate ``tilt`` [rad] and ``t_ns`` [ns, controller time]."""

    event_id: int
    body_id: int
    direction: int
    tilt: float
    t_ns: int


class FaultSource(NamedTuple):
    """Which device reported a fault and how: its ``node`` (on CANopen the node id, leg k's drive = node k) and
    the device's error ``code`` (CANopen: the EMCY error code, e.g. 0x8611 following error)."""

    node: int
    code: int


@dataclass(frozen=True)
class SetpointRefusal:
    """The controller refused setpoint chunk ``seq`` that reached it at ``t_ns`` [ns, controller time] for its
    values, and stopped the table (fault ``SETPOINT_REFUSED``); ``reason`` says which sample broke which limit."""

    t_ns: int
    seq: int
    reason: str


@dataclass(frozen=True)
class ControllerText:
    """A text the controller sent (MAVLink STATUSTEXT): its ``severity`` (``EMERGENCY`` … ``DEBUG``, MAV_SEVERITY's
    names) and ``text``, received at ``host_ns`` [ns, host monotonic] (the message carries no controller time)."""

    host_ns: int
    severity: str
    text: str


@dataclass(frozen=True)
class FaultEvent:
    """Fault bits that became set (``raised``) in the status at ``t_ns``; ``faults`` all latched, ``state`` then;
    ``sources`` the device reports that came with them, when the transport has them (CANopen: the EMCYs received
    since the previous status; empty elsewhere)."""

    t_ns: int
    raised: tuple[str, ...]
    faults: tuple[str, ...]
    state: str
    sources: tuple[FaultSource, ...] = ()


@dataclass(frozen=True, eq=False)
class StreamReport:
    """What :meth:`TableController.stream` did.

    ``chunks`` setpoint messages sent, ``samples`` poses in them; ``underruns`` dry spells the controller
    counted during the stream; ``t_start_ns``/``t_end_ns`` controller time of the first and last sample;
    ``duration`` [s] between them; ``lead`` [s] how far ahead of its first sample each chunk was due to be sent;
    ``send_lateness_ns`` (chunks,) actual send time − its deadline [ns, host clock; ≥ 0 unless the clock
    estimate moved]; ``final`` the status that ended the stream.
    """

    chunks: int
    samples: int
    underruns: int
    t_start_ns: int
    t_end_ns: int
    lead: float
    send_lateness_ns: np.ndarray
    final: TableStatus | None

    @property
    def duration(self) -> float:
        """Controller time from the first to the last sample [s]."""
        return (self.t_end_ns - self.t_start_ns) * 1e-9
