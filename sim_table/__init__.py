"""The emulated shake table: hexapod and actuator dynamics, physical specimens, protocol endpoints.

May import ``protocols`` and ``analysis``. Populated by the transports/emulator issue.
"""
