"""The shake table: `TableModel`, its limits, geometry, kinematics, trajectory check and configuration file.

This is the one table model of the project: the drive preparation (``rig``), the controller adapters
(``drivers``) and the emulator (``sim_table``) all import it (docs/architecture.md §1). Its parts are one job per
module, and their public names are re-exported here:

- `analysis.table.limits`: Table IV (`TABLE_IV`, `TableLimits`, `AxisLimits`, `TiltLimits`), `TableModelError`;
- `analysis.table.kinematics`: frames and poses, `HexapodGeometry`, `rotation_matrices`, leg lengths and rates;
- `analysis.table.checks`: the trajectory check (`Violation`, its numba kernel);
- `analysis.table.configuration`: the rig configuration file (TOML) and its physical ranges.

Units and frames as `analysis.table.kinematics` states them: SI inside, poses ``(..., 6)`` surge, sway, heave [m],
roll, pitch, yaw [rad]; the plate tilt β > 0 is pitch = +β (+x downhill).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import AnalysisInputError
from analysis.table.checks import AXIS_QUANTITIES, Violation, first_breach
from analysis.table.configuration import (
    DYNAMICS_KEYS,
    DYNAMICS_RANGES,
    MAX_JOINT_M,
    TableConfiguration,
    configuration_dict,
    configuration_from_dict,
    read_configuration,
)
from analysis.table.drives import DriveSettings
from analysis.table.dynamics import TableDynamics
from analysis.table.kinematics import HexapodGeometry, Legs, legs_at, pose_array, rotation_matrices
from analysis.table.limit_detectors import LimitDetectors
from analysis.table.limits import (
    AXES,
    TABLE_IV,
    TILTS,
    AxisLimits,
    TableLimits,
    TableModelError,
    TiltLimits,
    check_fields,
    positive,
)
from analysis.table.link import LinkSettings
from analysis.table.network import NetworkSettings
from analysis.table.sensors import SensorSheets

__all__ = [
    "AXES",
    "DYNAMICS_KEYS",
    "DYNAMICS_RANGES",
    "MAX_JOINT_M",
    "TABLE_IV",
    "TILTS",
    "AxisLimits",
    "HexapodGeometry",
    "TableLimits",
    "TableModel",
    "TableModelError",
    "TiltLimits",
    "Violation",
    "rotation_matrices",
]


@dataclass(frozen=True)
class TableModel:
    """Limits, geometry and setpoint rate [Hz] of the table, with its kinematics and trajectory check."""

    limits: TableLimits = TABLE_IV
    geometry: HexapodGeometry = field(default_factory=HexapodGeometry.default)
    controller_rate: float = 1000.0
    dynamics: TableDynamics = field(default_factory=TableDynamics)
    """The legs' servo-hydraulic parameters (``[dynamics]``; used by the emulator's ``--dynamics servo``)."""
    link: LinkSettings = field(default_factory=LinkSettings)
    """The host link's lead, buffer, watchdog and link timeout (``[controller]``, ``analysis.table.link``)."""
    drives: DriveSettings = field(default_factory=DriveSettings)
    """The leg drives' units, node ids, EDS files and options (``[drives]``, ``analysis.table.drives``)."""
    sensors: SensorSheets = field(default_factory=SensorSheets)
    """The accelerometers' calibration sheets (``[sensors]``, ``analysis.table.sensors``)."""
    detectors: LimitDetectors = field(default_factory=LimitDetectors)
    """Warning and abort levels on measured channels (``[limit_detectors]``, ``analysis.table.limit_detectors``)."""
    network: NetworkSettings = field(default_factory=NetworkSettings, compare=False)
    """This machine's TLS identity on the lab network (``[network]``, ``analysis.table.network``): not the table's,
    so not compared and not written by :meth:`to_dict`."""

    def __post_init__(self) -> None:
        if not isinstance(self.limits, TableLimits) or not isinstance(self.geometry, HexapodGeometry):
            raise TableModelError("TableModel: limits must be a TableLimits and geometry a HexapodGeometry")
        if not isinstance(self.dynamics, TableDynamics):
            raise TableModelError("TableModel: dynamics must be a TableDynamics")
        check_fields(self, positive, ("controller_rate",))

    # ----- kinematics -------------------------------------------------------------------------------

    def leg_lengths(self, poses: np.ndarray) -> np.ndarray:
        """Inverse kinematics: joint-to-joint leg lengths [m] ``(..., 6)`` of poses ``(..., 6)``."""
        return self._legs(pose_array(poses, "poses")).lengths()

    def leg_jacobian(self, poses: np.ndarray) -> np.ndarray:
        """d(leg lengths)/d(pose) ``(..., 6 legs, 6 pose coordinates)`` [m/m, m/rad] at poses ``(..., 6)``."""
        return self._legs(pose_array(poses, "poses")).jacobian()

    def leg_velocities(self, poses: np.ndarray, pose_rates: np.ndarray) -> np.ndarray:
        """Leg length rates [m/s] ``(..., 6)`` for poses and their time derivatives (Euler angle rates)."""
        rates = pose_array(pose_rates, "pose_rates")
        poses = pose_array(poses, "poses")
        poses, rates = np.broadcast_arrays(poses, rates)
        return self._legs(poses).rates(rates)

    def pose_from_leg_lengths(self, lengths: np.ndarray, guess: np.ndarray | None = None, *, tol: float = 1e-12,
                              max_iter: int = 50) -> np.ndarray:
        """Forward kinematics: the poses ``(..., 6)`` with leg lengths ``(..., 6)`` [m].

        Newton's method on the six IK residuals with the analytic Jacobian, from ``guess`` (default: home),
        until every leg-length residual is ≤ ``tol`` [m]. The hexapod has several assembly modes; the
        one found is the one Newton reaches from the guess (from home: the one the table runs in).
        Raises :class:`TableModelError` when it does not converge.
        """
        target = pose_array(lengths, "lengths")
        if np.any(target <= 0):
            raise AnalysisInputError("pose_from_leg_lengths: leg lengths must be > 0 m")
        x = np.zeros_like(target) if guess is None else np.array(np.broadcast_to(guess, target.shape), dtype=float)
        worst = math.inf
        for iteration in range(max_iter + 1):
            legs = self._legs(x)
            residual = legs.lengths() - target
            worst = float(np.max(np.abs(residual), initial=0.0))
            if worst <= tol:
                return x
            if iteration == max_iter or not math.isfinite(worst):
                break
            try:
                x = x - np.linalg.solve(legs.jacobian(), residual[..., None])[..., 0]
            except np.linalg.LinAlgError:
                raise TableModelError(f"forward kinematics: singular leg Jacobian after {iteration} Newton "
                                      f"iterations (largest leg-length residual {worst:.3e} m)") from None
        raise TableModelError(f"forward kinematics did not converge in {max_iter} Newton iterations: largest "
                              f"leg-length residual {worst:.3e} m (tolerance {tol:.1e} m)")

    def _legs(self, poses: np.ndarray) -> Legs:
        g = self.geometry
        return legs_at(g.base_joints, g.platform_joints, g.home_height, poses)

    # ----- limits -----------------------------------------------------------------------------------

    def check_trajectory(self, t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None = None,
                         accelerations: np.ndarray | None = None, *, rtol: float = 1e-9) -> Violation | None:
        """The first sample of a trajectory that leaves the table's limits, or None if it stays inside.

        ``t`` [s] ``(N,)`` strictly increasing, ``poses`` ``(N, 6)``; ``velocities`` and ``accelerations``
        ``(N, 6)`` (pose derivatives, Euler angle rates) when known, else ``np.gradient`` of poses and
        velocities over ``t``. Checked per sample: each leg's IK length within [leg_min, leg_max] and speed
        (``leg_velocities`` when velocities are given, else the gradient of the lengths) within leg_speed;
        each translational axis's displacement, velocity and acceleration; |roll|, |pitch| within the tilt
        angle and their rates within the tilt rate. A value counts as a violation only beyond
        ``limit (1 + rtol)``. Ties at one sample: legs before axes before tilts, then by index, then in the
        order just listed.
        """
        return first_breach(self.geometry, self.limits, t, poses, velocities, accelerations, AXIS_QUANTITIES, rtol)

    def check_command(self, t: np.ndarray, poses: np.ndarray, velocities: np.ndarray | None = None,
                      accelerations: np.ndarray | None = None, *, rtol: float = 1e-9) -> Violation | None:
        """The first sample of a *command* (the setpoints a drive streams) that leaves what the table enforces on
        its commands, or None: as :meth:`check_trajectory` but of the translational axes only the displacement.

        The controller clips a setpoint to the per-axis displacement envelope and the tilt angle, each leg's
        command to its stroke, and each leg's servo-valve saturates at the leg speed (``sim_table.dynamics``:
        |w| ≤ leg_speed, the feed-forward of the command's leg rate): those a command must respect to be played
        as written. Table IV's velocity and acceleration are the *plate's* (the response's): a compensated drive
        asks more acceleration than it gets where the table attenuates, and nothing in the table limits a
        command's acceleration — its response is what must stay within Table IV
        (``rig.compensation.safety.check_prediction``). Arguments and result as :meth:`check_trajectory`.
        """
        return first_breach(self.geometry, self.limits, t, poses, velocities, accelerations, ("displacement",), rtol)

    # ----- configuration ----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain JSON types in the TOML file's layout, SI keys, explicit joints."""
        return configuration_dict(TableConfiguration(self.limits, self.geometry, self.controller_rate,
                                                     self.dynamics, self.link, self.drives, self.sensors,
                                                     self.detectors))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> TableModel:
        """The model of a configuration mapping (the TOML file's layout); errors name ``source`` and the key."""
        return cls(*configuration_from_dict(data, source))

    @classmethod
    def from_toml(cls, path: str | Path) -> TableModel:
        """The model of a rig configuration file (`analysis.table.configuration`); Table IV and the default
        geometry for what it leaves out.

        Only a regular file of at most 1 MiB is read (`analysis.table.toml_check.read_toml`)."""
        return cls(*read_configuration(path))
