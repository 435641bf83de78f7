"""The emulated shake table: hexapod and actuator dynamics, physical specimens, protocol endpoints.

May import ``protocols`` and ``analysis``. Run it as ``python -m sim_table --listen mavlink://HOST:PORT`` (or
``rig emulate``).

- ``scene``: the specimens of a test and the MuJoCo model of them standing on the plate.
- ``specimens``: :class:`~sim_table.specimens.SpecimenScene`, the bodies riding the driven plate, and
  their overturns.
- ``controller``: the controller's states, commands, setpoint buffer, watchdogs and counters, transport-free.
- ``actuators``: the six legs on the table model (lag, speed and stroke limits, measurement noise).
- ``accelerometers``: the plate's motion differentiated; virtual accelerometers (specific force, plate frame).
- ``mavlink_endpoint``: the controller's MAVLink 2 side over UDP.
- ``process``: the emulator process (the tick loop, its options, fault injection, exit counters).
"""
