"""Drive preparation: earthquake records → table-ready 6-DOF trajectories inside the table's limits.

`prepare_drive` is the entry point (see `rig.drive.prepare`); `rig.drive.processing` holds the signal
chain, `rig.drive.tilt` the jerk-limited tilt ramp and `rig.drive.file` a prepared (e.g. compensated) drive as
an HDF5 file a sequence plays.
"""

from .prepare import Drive, DriveError, DriveRefusedError, Governing, parse_headroom, prepare_drive

__all__ = ["Drive", "DriveError", "DriveRefusedError", "Governing", "parse_headroom", "prepare_drive"]
