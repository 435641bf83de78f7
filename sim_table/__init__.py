"""The emulated shake table: hexapod and actuator dynamics, physical specimens, protocol endpoints.

May import ``protocols`` and ``analysis``. Run it as ``python -m sim_table --listen URL`` (or ``rig emulate``)
with ``mavlink://HOST:PORT``, ``zenoh://HOST:PORT/TABLE`` or ``canopen://CHANNEL?interface=…``.

- ``scene``: the specimens of a test and the MuJoCo model of them standing on the plate.
- ``specimens``: :class:`~sim_table.specimens.SpecimenScene`, the bodies riding the driven plate, and
  their overturns.
- ``controller``: the controller's states, commands, setpoint buffer, watchdogs and counters, transport-free.
- ``actuators``: the six legs on the table model (lag, speed and stroke limits, measurement noise).
- ``forward_kinematics``: leg lengths → plate poses, the table model's Newton compiled (numba), pose by pose.
- ``dynamics``: servo-hydraulic legs (valve, oil column, displacement loop; ``--dynamics servo``).
- ``offline``: a drive played through the legs and accelerometers without transport or clock.
- ``accelerometers``: the plate's motion differentiated; virtual accelerometers (specific force, plate frame).
- ``endpoint``: the transport endpoints' interface, chosen by the listen URL's scheme.
- ``mavlink_endpoint``, ``zenoh_endpoint``, ``canopen_endpoint``: the controller's side of each transport.
  ``canopen_endpoint`` is the import surface of the package ``canopen`` (bus plumbing, SYNC timing, history,
  node models, counters, the endpoint: one job per module).
- ``process``: the emulator process (the tick loop, its options, fault injection, exit counters).
- ``tick_profile``: the tick thread's CPU time split by stage (physics, servo, transport…), in the exit counters.
"""
