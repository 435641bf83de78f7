"""A stream as the CANopen master plays it: the trajectory's poses, interpolated at any controller time."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A stream: ``poses`` (N, 6) due at ``t_start_ns + k·spacing_ns``, blended into linearly from the pose
    ``anchor`` held at ``anchor_ns``."""

    anchor_ns: int
    anchor: np.ndarray
    t_start_ns: int
    spacing_ns: int
    poses: np.ndarray

    @property
    def t_end_ns(self) -> int:
        return self.t_start_ns + (len(self.poses) - 1) * self.spacing_ns

    def due(self, t_ns: int) -> int:
        """Samples due by ``t_ns``."""
        return min(len(self.poses), max(0, (t_ns - self.t_start_ns) // self.spacing_ns + 1))

    def at(self, t_ns: int) -> np.ndarray:
        if t_ns < self.t_start_ns:
            share = (t_ns - self.anchor_ns) / (self.t_start_ns - self.anchor_ns)
            return self.anchor + (self.poses[0] - self.anchor) * max(0.0, share)
        k = (t_ns - self.t_start_ns) / self.spacing_ns
        if k >= len(self.poses) - 1:
            return self.poses[-1].copy()
        i = int(k)
        return self.poses[i] + (self.poses[i + 1] - self.poses[i]) * (k - i)
