"""The emulated shake table: hexapod and actuator dynamics, physical specimens, protocol endpoints.

May import ``protocols`` and ``analysis``. Populated by the transports/emulator issue.

- ``scene``: the specimens of a test and the MuJoCo model of them standing on the plate.
- ``specimens``: :class:`~sim_table.specimens.SpecimenScene`, the bodies riding the driven plate, and
  their overturns.
"""
