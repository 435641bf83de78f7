"""What the orchestrator writes to: the session log and the run being recorded, as typed protocols.

:class:`rig.session.SessionLog` and :class:`rig.session.RunLog` are the implementations; the orchestrator and
its run recorder depend only on these methods (a test double or another store provides the same). Times are
seconds on the run's clock (0 = the drive's first sample, ``docs/orchestrator.md``), accelerations [m/s²] in the
plate frame, poses (surge, sway, heave [m], roll, pitch, yaw [rad]).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class RunSink(Protocol):
    """The run being recorded (:class:`rig.session.RunLog`)."""

    def append_accel(self, sensor: str, t: np.ndarray, xyz: np.ndarray) -> None:
        """Accelerometer samples: ``t`` (k,) [s], ``xyz`` (k, 3) [m/s²]."""

    def append_tilt(self, body_id: int, t: np.ndarray, angle: np.ndarray) -> None:
        """A body's tilt-sensor samples: ``t`` (k,) [s], ``angle`` (k,) [rad, relative to the plate, > 0 towards
        the low side]."""

    def append_pose(self, t: np.ndarray, pose: np.ndarray) -> None:
        """Measured table pose: ``t`` (k,) [s], ``pose`` (k, 6)."""

    def append_following_error(self, t: np.ndarray, errors: np.ndarray) -> None:
        """Each leg's following error: ``t`` (k,) [s], ``errors`` (k, 6) [m], legs 1…6."""

    def add_detection(self, t: float, body_id: int, direction: int, source: str) -> None:
        """An overturn at ``t`` [s]: direction +1 low side, −1 high side; source ``"sensor"``/``"operator"``."""

    def add_fault(self, t: float, name: str, detail: str) -> None:
        """A fault reported at ``t`` [s]."""

    def add_event(self, t: float, text: str) -> None:
        """A log line at ``t`` [s] (NaN: no time on the run's clock)."""

    def end(self, status: str, **attrs: Any) -> object:
        """End the run with ``status`` (``completed``, ``aborted``, ``refused``…) and final attributes."""


@runtime_checkable
class SessionSink(Protocol):
    """The session file being written (:class:`rig.session.SessionLog`, new or resumed)."""

    @property
    def path(self) -> Path:
        """The session file (its file system is checked for room before each run)."""

    def done_plan_indices(self) -> set[int]:
        """Plan indices that must not run again (a completed or refused run)."""

    def begin_run(self, plan_index: int, *, record: str, scale_factor: float, angle_deg: float,
                  commanded: np.ndarray, bodies: Iterable[Mapping[str, Any]], sensors: Sequence[str],
                  attrs: Mapping[str, Any] | None = None) -> RunSink:
        """Open the run of plan entry ``plan_index``: ``commanded`` (N, 7) t [s] and pose, ``angle_deg`` [°]."""
