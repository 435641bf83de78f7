"""The emulated table's physics without a transport or a clock: a drive played straight through the legs.

:func:`play_offline` gives what the emulator's accelerometers would report for a drive (``rig emulate`` runs the same
legs, :class:`~sim_table.accelerometers.PlateTrack` and :class:`~sim_table.accelerometers.Accelerometers` on the same
1 kHz ticks, with the setpoints on the drive's own samples): used to check the drive compensation's convergence
quickly and independently of the machine's load (tests, ``benchmarks/compensation.py``). The specimens' reaction on
the plate is their mass on the legs (the emulator's MuJoCo plate is driven kinematically, so they add nothing else).
"""

from __future__ import annotations

import numpy as np

from analysis.table.model import TableModel
from sim_table.accelerometers import Accelerometers, PlateTrack
from sim_table.actuators import ActuatorSettings
from sim_table.dynamics import make_actuators

BATCH = 1000
"""Ticks per call of the legs' model."""


def play_offline(table: TableModel, poses: np.ndarray, *, dynamics: str = "servo", payload: float = 0.0,
                 sensor: tuple[float, float, float] = (0.0, 0.0, 0.0), accel_noise: float = 0.02,
                 leg_noise: float = 1e-6, seed: int = 0) -> np.ndarray:
    """The plate-frame specific force (n, 3) [m/s²] an accelerometer at plate ``sensor`` [m] measures while the
    table plays ``poses`` (n, 6), one per controller tick, starting at rest at ``poses[0]``; ``payload`` [kg] of
    specimens on the plate; ``dynamics`` as ``rig emulate --dynamics``."""
    poses = np.asarray(poses, dtype=float)
    dt = 1.0 / table.controller_rate
    legs = make_actuators(dynamics, table, dt, ActuatorSettings(noise=leg_noise), payload=payload, pose=poses[0],
                          seed=seed)
    achieved = np.concatenate([legs.step(poses[i:i + BATCH], np.zeros(len(poses[i:i + BATCH]), bool)).poses
                               for i in range(0, len(poses), BATCH)])
    track = PlateTrack(dt, poses[0])
    _, _, window = track.advance(np.vstack([achieved, achieved[-1:]]))
    sensors = Accelerometers(np.array([sensor]), dt, noise=accel_noise, seed=seed + 1)
    return sensors.measure(window[1:])[:, 0, :]
