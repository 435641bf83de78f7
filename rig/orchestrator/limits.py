"""The limit detectors (``analysis.table.limit_detectors``, ``docs/limits.md``) evaluated on the host as the
table's feedback arrives: one numpy pass per batch, a few comparisons per sample.

:class:`LimitWatch` takes what the run recorder receives — accelerometer batches, body tilt batches, the
controller's statuses (pose; the velocity between consecutive statuses; the legs' following errors) — and returns
the :class:`Trip` of every level passed for its detector's persistence. Each level of each channel instance
(``accel.0.x``: accelerometer 0's x; ``tilt.2.angle``: body 2's tilt sensor; ``pose.heave``; ``velocity.roll``;
``leg.3.following_error``: leg 3's) trips at most once per run. Times are the run's [s]; values and levels SI
(m/s², m, rad, m/s, rad/s, s).

``link.age`` (:class:`LinkAge`) is the host's own: the age of the latest status on the host's clock, sampled every
:data:`LINK_AGE_PERIOD_NS` of host time from the run's first status on, whether statuses come or not (the recorder
calls :meth:`LimitWatch.link` from its loop, at least every 20 ms, with the statuses' arrival times).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from analysis.table.limit_detectors import (
    CHANNELS,
    POSE_AXES,
    Detector,
    LimitDetectors,
    StatusVelocity,
    first_trip,
    is_past,
)
from drivers.controller import FaultEvent
from protocols.canopen.od import EMCY_FOLLOWING_ERROR, EMCY_REFERENCE_LIMIT


@dataclass(frozen=True)
class Trip:
    """A level passed: ``channel`` (the instance, e.g. ``accel.0.x``), ``level`` (``warn_high`` …), the sample's
    ``value`` and the level's ``threshold`` [``unit``, SI], its time ``t`` [s, run time] (the sample that completed
    the persistence) and the ``action`` taken (``record`` for a warning; the detector's for an abort level);
    ``source`` who found it: ``host`` (:class:`LimitWatch`) or ``controller`` (its own levels, reported; or one of
    its own limits, :func:`controller_limits`, whose ``value`` and ``threshold`` it does not report: NaN, and
    ``detail`` says what it reported)."""

    channel: str
    level: str
    value: float
    threshold: float
    unit: str
    t: float
    action: str
    source: str = "host"
    detail: str = ""

    def text(self) -> str:
        """The session event's line: ``limit accel.0.x: 6.02 m/s² past abort high 5.886 m/s²: controlled_stop
        (host)``; a controller's own limit: ``limit leg.stroke: past the controller's limit (a leg's command
        reached its stroke): controlled_stop (controller)``."""
        if math.isnan(self.value):
            return f"limit {self.channel}: past the controller's limit ({self.detail}): {self.action} ({self.source})"
        return (f"limit {self.channel}: {self.value:.4g} {self.unit} past {self.level.replace('_', ' ')} "
                f"{self.threshold:.4g} {self.unit}: {self.action} ({self.source})")


class ChannelWatch:
    """One detector on one instance of its channel (``name``), its levels' consecutive counts across batches."""

    def __init__(self, detector: Detector, name: str) -> None:
        self.detector = detector
        self.name = name
        self._carry = {level: 0 for level, _ in detector.levels()}
        self._tripped: set[str] = set()

    def feed(self, t: np.ndarray, values: np.ndarray) -> list[Trip]:
        """The trips in samples ``values`` [SI] at times ``t`` [s], earliest first."""
        trips = []
        for level, threshold in self.detector.levels():
            if level in self._tripped:
                continue
            past = is_past(values, threshold, level)
            index, self._carry[level] = first_trip(past, self._carry[level], self.detector.persistence)
            if index is not None:
                self._tripped.add(level)
                action = self.detector.action if level.startswith("abort") else "record"
                trips.append(Trip(self.name, level, float(values[index]), threshold,
                                  CHANNELS[self.detector.channel].si, float(t[index]), action))
        return sorted(trips, key=lambda trip: trip.t)


LINK_AGE_PERIOD_NS = 10_000_000
"""How often ``link.age`` is sampled [ns, host time]: half a status period at 50 statuses a second, so a
persistence counts 10 ms steps."""


class LinkAge:
    """The ``link.age`` samples: at host times ``first arrival + k × period`` [ns], the age of the latest status
    that had arrived by then [s] and the run time of the sample (that status's run time plus its age: the
    controller's clock carried on by the host's). Samples are taken up to the ``now`` the caller gives, so a silent
    link yields samples as well as a lively one, and the caller's loop only decides how soon they are seen."""

    def __init__(self, period_ns: int = LINK_AGE_PERIOD_NS) -> None:
        self.period_ns = period_ns
        self._latest: tuple[int, float] | None = None  # (host ns, run time [s]) of the latest status sampled
        self._pending: deque[tuple[int, float]] = deque()  # arrived after the last sample's host time
        self._next_ns: int | None = None

    def arrived(self, host_ns: int, t: float) -> None:
        """A status of run time ``t`` [s] arrived at host monotonic time ``host_ns`` [ns]."""
        if self._next_ns is None:
            self._latest, self._next_ns = (host_ns, t), host_ns + self.period_ns
        else:  # one stamped before a sample already taken is the latest for the samples to come, if none is newer
            self._pending.append((host_ns, t))

    def sample(self, now_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """The samples due up to host time ``now_ns`` [ns]: their run times [s] and ages [s]."""
        times: list[float] = []
        ages: list[float] = []
        while self._next_ns is not None and self._next_ns <= now_ns:
            while self._pending and self._pending[0][0] <= self._next_ns:
                candidate = self._pending.popleft()
                assert self._latest is not None
                if candidate[0] >= self._latest[0]:
                    self._latest = candidate
            assert self._latest is not None
            age = (self._next_ns - self._latest[0]) * 1e-9
            times.append(self._latest[1] + age)
            ages.append(age)
            self._next_ns += self.period_ns
        return np.array(times), np.array(ages)


class LimitWatch:
    """The run's detectors (module docstring): fed by the run recorder, one instance per run."""

    def __init__(self, detectors: LimitDetectors) -> None:
        self._detectors = {d.channel: d for d in detectors.detectors}
        self._watches: dict[str, ChannelWatch] = {}
        self._velocity = StatusVelocity()
        self._link_age = LinkAge()

    def _watch(self, channel: str, name: str) -> ChannelWatch | None:
        detector = self._detectors.get(channel)
        if detector is None:
            return None
        if name not in self._watches:
            self._watches[name] = ChannelWatch(detector, name)
        return self._watches[name]

    def _feed(self, channel: str, name: str, t: np.ndarray, values: np.ndarray) -> list[Trip]:
        watch = self._watch(channel, name)
        return [] if watch is None else watch.feed(t, values)

    def accel(self, sensor: str, t: np.ndarray, xyz: np.ndarray) -> list[Trip]:
        """Accelerometer ``sensor``'s samples: ``t`` (k,) [s], ``xyz`` (k, 3) [m/s², plate frame]."""
        trips = []
        for k, axis in enumerate("xyz"):
            trips += self._feed(f"accel.{axis}", f"accel.{sensor}.{axis}", t, xyz[:, k])
        return sorted(trips, key=lambda trip: trip.t)

    def tilt(self, body_id: int, t: np.ndarray, angle: np.ndarray) -> list[Trip]:
        """Body ``body_id``'s tilt sensor: ``t`` (k,) [s], ``angle`` (k,) [rad]."""
        return self._feed("tilt.angle", f"tilt.{body_id}.angle", t, angle)

    def following_errors(self, t: np.ndarray, errors: np.ndarray) -> list[Trip]:
        """The statuses' leg following errors: ``t`` (k,) [s], ``errors`` (k, 6) [m, commanded minus measured
        length], legs 1…6 (``leg.1.following_error`` …)."""
        trips = []
        for leg in range(errors.shape[1]):
            trips += self._feed("leg.following_error", f"leg.{leg + 1}.following_error", t, errors[:, leg])
        return sorted(trips, key=lambda trip: trip.t)

    def poses(self, t: np.ndarray, pose: np.ndarray) -> list[Trip]:
        """The statuses' measured poses: ``t`` (k,) [s], ``pose`` (k, 6) (m, rad); the velocity is the difference
        of consecutive statuses over their time step (the first status of a run has none)."""
        trips = []
        t_velocity, velocity = self._velocity.feed(t, pose)
        for k, axis in enumerate(POSE_AXES):
            trips += self._feed(f"pose.{axis}", f"pose.{axis}", t, pose[:, k])
            trips += self._feed(f"velocity.{axis}", f"velocity.{axis}", t_velocity, velocity[:, k])
        return sorted(trips, key=lambda trip: trip.t)

    def link(self, arrivals: Iterable[tuple[int, float]], now_ns: int) -> list[Trip]:
        """``link.age`` (:class:`LinkAge`) up to host monotonic time ``now_ns`` [ns], after the statuses that
        arrived since the last call: (host ns of the arrival, run time [s]) each."""
        if "link.age" not in self._detectors:
            return []
        for host_ns, t in arrivals:
            self._link_age.arrived(host_ns, t)
        t_samples, ages = self._link_age.sample(now_ns)
        return self._feed("link.age", "link.age", t_samples, ages)


FAULT_LIMITS = {
    "STROKE": ("leg.stroke", "a leg's command reached its stroke"),
    "SETPOINT_LIMIT": ("setpoint.envelope", "a reference was clipped to the envelope or a leg's speed"),
    "SETPOINT_REFUSED": ("setpoint.refused", "a setpoint chunk held a sample beyond the table's limits"),
}
"""The fault bits that are a controller's own limits: the channel they are recorded as, what the bit means."""

EMCY_LIMITS = {
    EMCY_FOLLOWING_ERROR: ("following_error", "EMCY 0x8611 following error", "DRIVE"),
    EMCY_REFERENCE_LIMIT: ("reference", "EMCY 0x8612 reference limit", "SETPOINT_REFUSED"),
}
"""The CiA 402 drives' EMCY codes that are a limit of leg (node) N: the channel ``leg.N.<name>``, what it means,
the fault bit the master latches for it."""

_FAULT_ACTIONS = {"stopping": "controlled_stop", "faulted": "controlled_stop", "emergency_stopped": "emergency_stop"}
"""What the controller did, by its state with the fault (otherwise the fault only latched: ``record``)."""


def controller_limits(fault: FaultEvent, t: float) -> list[Trip]:
    """The controller's own limits among the faults ``fault`` raised at ``t`` [s, run time], as trips marked
    ``controller``: a drive's EMCY of a limit names its leg (CANopen: node N is leg N); the fault bits of
    :data:`FAULT_LIMITS` otherwise."""
    action = _FAULT_ACTIONS.get(fault.state, "record")
    emcys = [(source.node, EMCY_LIMITS[source.code]) for source in fault.sources if source.code in EMCY_LIMITS]
    trips = [Trip(f"leg.{node}.{name}", "limit", math.nan, math.nan, "", t, action, "controller", detail)
             for node, (name, detail, _) in emcys]
    named = {bit for _, (_, _, bit) in emcys}  # said by the drives, leg by leg
    for bit in fault.raised:
        if bit in FAULT_LIMITS and bit not in named:
            channel, detail = FAULT_LIMITS[bit]
            trips.append(Trip(channel, "limit", math.nan, math.nan, "", t, action, "controller", detail))
    return trips
