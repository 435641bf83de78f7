"""The machine: the shake table's geometry, limits and moves, its servo-hydraulic parameters and its TOML
configuration — what `rig`, `drivers` and `sim_table` share about the table, apart from the overturning physics.

- ``model``: :class:`TableModel` (Table IV limits, hexapod geometry and kinematics, the rig TOML), over
  ``limits`` (Table IV, `TableModelError`), ``kinematics`` (frames, poses, `HexapodGeometry`, leg lengths and
  rates), ``checks`` (the trajectory check's numba kernel) and ``configuration`` (the rig TOML's reader);
- ``moves``: jerk-limited point-to-point moves (tilt, home) and their durations;
- ``setpoints``: the setpoint check host and controller share, and ``setpoint_screen`` its compiled screen (a chunk
  clearly inside every limit, in one numba pass; any other left to the check);
- ``dynamics``: the legs' servo-hydraulic parameters (``[dynamics]``, ``docs/table-dynamics.md``);
- ``toml_lines``: TOML keys to the lines they are on, for errors that name FILE:LINE.
"""
