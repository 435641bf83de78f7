"""What several test modules share, imported as ``tests.helpers.<module>`` (a test module never imports another):

- `newton_euler`: the rigid block's equations written independently of `analysis` (the general model's truth).
- `streams`, `table_checks`: drives to stream and the checks every transport's table must pass.
- `owner`: a host that owns a table and streams a run while the test stands for another host beside it.
- `sequences`: the small sequences the orchestrator, CLI and service tests play, and playing one on an emulator.
- `sensor_sheets`: accelerometer and tilt sensor sheets as the rig configuration's ``[sensors]`` TOML.
- `processes`: free ports, `rig` and its children as processes, waiting for a condition.
- `console`: the console's test controls and headers, and Chromium's flags for the browser tests.
- `session_writer`: the session-file writer and reader processes the ``kill -9`` campaigns start.
- `feedback`: a table as the run recorder sees it (a real feedback hub the test feeds).
- `link_cut`: the rig's side of the link-loss test, run in its network namespace (plays, then takes its link down).

Fixtures live in the ``conftest.py`` of the folder that uses them (``tests/conftest.py`` for all).
"""
