"""The commands on the caller's thread (package docstring, the table's behaviour): ARM, DISARM, HOME, SET_TILT,
STOP, EMERGENCY_STOP and streams; and the reference pose the cycle plays (a move, a stream, a stop's deceleration
and return home)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from analysis.table.moves import Move
from drivers.canopen.master import DRIVING_STATES, MasterBase
from drivers.canopen.nodes import NMT_OPERATIONAL
from drivers.canopen.trajectory import Trajectory
from drivers.controller import (
    DEFAULT_LEAD,
    STATUS_TIMEOUT,
    STOPPED_STATES,
    TILT_AXES,
    CommandFailedError,
    CommandRejectedError,
    StreamAbortedError,
    StreamReport,
    TableError,
    TableTimeoutError,
    playable_poses,
    sample_spacing,
)
from protocols.canopen import State

STATUS_WAIT = 0.1
"""After a command, wait up to this long [s] for the status that shows it."""

_MOVING = frozenset({"homing", "tilting", "streaming"})


class Motions(MasterBase):
    """The commands, and the reference (:meth:`_reference`) the cycle sends the drives."""

    def _reference(self, tau: int) -> np.ndarray | None:
        """The reference pose at ``tau`` (None when the drives hold their own positions)."""
        if not (self._state in DRIVING_STATES or (self._state == "stopping" and self._stop_reason is None)):
            return None
        dt = (tau - self._tau) * 1e-9 if self._tau else self.period_ns * 1e-9
        previous = self._pose
        if self._state in ("homing", "tilting") and self._move is not None:
            pose = self._move.at(tau)
        elif self._state == "streaming" and self._trajectory is not None:
            pose = self._trajectory.at(tau)
        elif self._state == "stopping" and self._move is not None:
            pose = self._move.at(tau)
        elif self._state == "stopping":  # decelerate at the axis limits, then move home
            slower = np.sign(self._velocity) * np.maximum(np.abs(self._velocity) - self._acceleration * dt, 0.0)
            pose = previous + slower * dt
            if not slower.any():
                self._move = Move.shortest(tau, pose, np.zeros(6), self.table)
                self._homing_after_stop = True
        else:
            pose = previous
        self._velocity = (pose - previous) / dt if dt > 0 else np.zeros(6)
        self._pose, self._tau = pose, tau
        return pose

    def _refuse(self, name: str, why: str) -> None:
        raise CommandRejectedError(name, "TEMPORARILY_REJECTED", self._state, why)

    def _status_after(self, now: int) -> None:
        """Wait (at most :data:`STATUS_WAIT` real seconds) for a status made after ``now`` [ns, the master's clock]:
        it shows what a command did."""
        self.feedback.wait_for(lambda: self.feedback.latest is not None and self.feedback.latest.host_ns > now,
                               STATUS_WAIT)

    def _wait_state(self, name: str, done: Callable[[], bool], timeout: float) -> None:
        if not self.feedback.wait_for(lambda: done() or self._failure is not None, timeout):
            states = ", ".join(f"leg {leg} {link.state.value if link.state else 'silent'}"
                               for leg, link in enumerate(self._drives, start=1))
            raise TableTimeoutError(f"{name}: not done within {timeout} s ({states})")
        self._check_alive()

    def arm(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state not in ("idle", "armed", "faulted", "emergency_stopped"):
                self._refuse("ARM", "not accepted in this state")
            now = self.clock.now_ns()
            silent = [leg for leg, link in enumerate(self._drives, start=1) if self.silent(link, now)]
            if silent:
                raise CommandFailedError("ARM", "FAILED", self._state,
                                         f"no heartbeat from leg {', '.join(map(str, silent))}")
            stopped = [leg for leg, link in enumerate(self._drives, start=1) if link.nmt_state != NMT_OPERATIONAL]
            if stopped:  # its PDOs do not work (a drive that rebooted has lost its configuration: connect again)
                legs = ", ".join(map(str, stopped))
                raise CommandFailedError("ARM", "FAILED", self._state,
                                         f"leg {legs} not NMT operational ({self._nmt_states()})")
            self._faults.clear()
            self.silent_drives.clear()
            self._stop_reason = None
            if self._state == "armed":
                return
            self._arming = True
        try:
            self._wait_state("ARM", lambda: self._state == "armed" and not self._arming, self.command_timeout)
        except TableError:
            with self._lock:
                self._arming = False
            raise
        self._status_after(self.clock.now_ns())

    def disarm(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state not in ("idle", "armed", "faulted"):
                self._refuse("DISARM", "only at rest (armed or faulted)")
            self._set_state("idle")  # the drives are told to disable operation from the next cycle
        self._wait_state("DISARM", lambda: not any(link.state is State.OPERATION_ENABLED for link in self._drives),
                         self.command_timeout)
        self._status_after(self.clock.now_ns())

    def _motion(self, name: str, target: Callable[[np.ndarray], np.ndarray], state: str, wait: bool,
                timeout: float) -> None:
        """Start a move from the reference to ``target(reference)``; with ``wait``, until it is over."""
        self._check_alive()
        with self._lock:
            if self._state != "armed":
                self._refuse(name, "not accepted in this state")
            move = Move.shortest(self._tau, self._pose, target(self._pose.copy()), self.table)
            if move.duration_ns == 0:
                return
            self._move = move
            self._set_state(state)
        if not wait:
            return
        self._wait_state(name, lambda: self._state != state, timeout)
        if self._state != "armed":
            raise CommandFailedError(name, "FAILED", self._state, "the motion was stopped before its target")
        shown = self._arrived_ns  # the status of the SYNC found in position (published in the same cycle)
        self.wait_for_status(lambda s: s.t_ns >= shown, STATUS_TIMEOUT)

    def home(self, *, wait: bool = True, timeout: float = 120.0) -> None:
        self._motion("HOME", lambda pose: np.zeros(6), "homing", wait, timeout)

    def set_tilt(self, angle: float, axis: str = "pitch", *, wait: bool = True, timeout: float = 120.0) -> None:
        if axis not in TILT_AXES:
            raise ValueError(f"axis must be one of {TILT_AXES}, got {axis!r}")
        if not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle!r}")
        if abs(angle) > self.table.limits.tilt.angle:
            raise CommandFailedError("SET_TILT", "FAILED", self._state,
                                     f"invalid parameters: |{angle}| rad beyond the tilt limit "
                                     f"{self.table.limits.tilt.angle} rad")
        column = 4 if axis == "pitch" else 3

        def tilted(pose: np.ndarray) -> np.ndarray:
            pose[column] = angle
            return pose

        self._motion("SET_TILT", tilted, "tilting", wait, timeout)

    def stop(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state in _MOVING:
                self._move = self._trajectory = None
                self._stop_reason = None
                self._set_state("stopping")
        self._status_after(self.clock.now_ns())

    def emergency_stop(self) -> None:
        self._check_alive()
        with self._lock:
            self._arming = False
            self._move = self._trajectory = None
            self._set_state("emergency_stopped")
        self._status_after(self.clock.now_ns())

    def stream(self, t: np.ndarray, poses: np.ndarray, *, lead: float = DEFAULT_LEAD,
               on_progress: Callable[[int, int], None] | None = None,
               on_start: Callable[[int], None] | None = None) -> StreamReport:
        self._check_alive()
        spacing = sample_spacing(t, len(poses))
        spacing_ns = round(spacing * 1e9)
        shortest = (self.target_delay_ns + self.period_ns) * 1e-9
        if not (math.isfinite(lead) and lead > shortest):
            raise ValueError(f"lead must exceed {shortest:g} s (the drives' target delay and a cycle), got {lead!r}")
        with self._lock:
            held = self._pose.copy()
        poses = playable_poses(self.url, self.table, poses, spacing, (held, lead - shortest))  # the blend's least
        self.heap.hold()  # refreeze: what the runs before made is not visited by the stream's collections
        with self._lock:
            if self._state != "armed":
                self._refuse("START_STREAM", "not accepted in this state")
            now = self.clock.now_ns()
            anchor = max(self._tau, self._next_deadline + self.target_delay_ns)
            trajectory = Trajectory(anchor, self._pose.copy(), now + round(lead * 1e9), spacing_ns, poses)
            self._trajectory = trajectory
            underruns_before = self._underruns
            self._lateness, self._stream_cycles, self._dry = [], 0, False
            self._set_state("streaming")
        if on_start is not None:
            on_start(trajectory.t_start_ns)
        next_progress = time.monotonic_ns() + 100_000_000
        while not self.feedback.wait_for(lambda: self._state != "streaming" or self._failure is not None,
                                         max(0.0, (next_progress - time.monotonic_ns()) * 1e-9)):
            if on_progress is not None:
                on_progress(trajectory.due(self._tau), len(poses))
            next_progress += 100_000_000
        self._check_alive()
        final = self.wait_for_status(lambda s: s.state != "streaming", STATUS_TIMEOUT)
        if on_progress is not None:
            on_progress(trajectory.due(self._tau) if final.state in STOPPED_STATES else len(poses), len(poses))
        with self._lock:
            lateness = np.array(self._lateness or [], dtype=np.int64)
            self._lateness = None
            report = StreamReport(self._stream_cycles, len(poses), self._underruns - underruns_before,
                                  trajectory.t_start_ns, trajectory.t_end_ns, lead, lateness, final)
            played = self._played is trajectory
        if final.state != "armed" or not played:  # stopped (and home again) before its end
            refused = (": a leg drive refused its target (EMCY 0x8612, reference limit)"
                       if "SETPOINT_REFUSED" in final.faults else "")
            raise StreamAbortedError(f"the table stopped the stream ({final.state}, faults "
                                     f"{', '.join(final.faults) or 'none'}){refused}", report)
        return report
