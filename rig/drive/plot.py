"""Figure of a prepared drive: original and prepared acceleration, velocity and displacement, with limits.

One column per driven axis (surge, lateral, heave), rows acceleration [g], velocity [m/s], displacement
[m], and a last row with the tilt [deg]. The original record is drawn at its place in the drive's time
(``Drive.record_start``), unscaled, with its velocity and displacement integrated from rest without any
processing — the drift the processing removes is part of the picture. The table's limits are dashed.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rig.records import G, GroundMotion

from .prepare import AXIS_COMPONENTS, POSE_COLUMN, Drive
from .processing import integrate_from_rest

_ROWS = (("acceleration", "acceleration [g]", 1.0 / G), ("velocity", "velocity [m/s]", 1.0),
         ("displacement", "displacement [m]", 1.0))


def plot_drive(motion: GroundMotion, drive: Drive, path: str | Path) -> Path:
    """Write the figure to ``path`` (PNG, or any format matplotlib knows by the suffix) and return it."""
    path = Path(path)
    axes_names = drive.components
    width = max(8.0, 5.5 * len(axes_names))
    fig, grid = plt.subplots(4, len(axes_names), figsize=(width, 10), sharex=True, squeeze=False)
    t_record = drive.record_start + motion.time
    for col, axis in enumerate(axes_names):
        raw = np.asarray(getattr(motion, AXIS_COMPONENTS[axis])) * G
        raw_vel, raw_disp = integrate_from_rest(raw, motion.dt)
        original = {"acceleration": raw, "velocity": raw_vel, "displacement": raw_disp}
        prepared = {"acceleration": drive.accelerations, "velocity": drive.velocities, "displacement": drive.poses}
        bounds = drive.table.limits.axis(axis)
        for row, (quantity, label, to_unit) in enumerate(_ROWS):
            ax = grid[row][col]
            ax.plot(t_record, original[quantity] * to_unit, color="0.6", lw=0.7, label="original record (scale 1)")
            ax.plot(drive.t, prepared[quantity][:, POSE_COLUMN[axis]] * to_unit, color="C0", lw=0.8,
                    label=f"prepared drive (scale {drive.scale_factor:.3g})")
            limit = getattr(bounds, quantity) * to_unit
            for sign in (1, -1):
                ax.axhline(sign * limit, color="C3", ls="--", lw=0.8, label="table limit" if sign > 0 else None)
            ax.set_ylabel(label)
            ax.set_ylim(-1.6 * limit, 1.6 * limit)
            ax.grid(alpha=0.3)
        grid[0][col].set_title(f"{axis}")
        tilt_ax = grid[3][col]
        tilt_ax.plot(drive.t, np.degrees(drive.poses[:, 4]), color="C2", lw=1.0, label="tilt (pitch)")
        tilt_ax.axhline(math.degrees(drive.table.limits.tilt.angle), color="C3", ls="--", lw=0.8)
        tilt_ax.set_ylabel("tilt [deg]")
        tilt_ax.set_xlabel("drive time [s]")
        tilt_ax.grid(alpha=0.3)
    grid[0][0].legend(loc="upper right", fontsize="small")
    gov = drive.governing
    fig.suptitle(
        f"{drive.record} at tilt {math.degrees(drive.angle):g}°\nscale factor {drive.scale_factor:.3g} "
        f"({gov.axis} {gov.quantity}{' governs' if gov.binding else ' closest, not binding'}), "
        f"high-pass corner {drive.corner_frequency:.3g} Hz"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
