"""The emulator's CANopen side, one job per module as the master (``drivers/canopen/``) is cut:

- :mod:`~sim_table.canopen.bus`: the bus plumbing (python-can's ``virtual`` bus passing time stamps on, COB-IDs);
- :mod:`~sim_table.canopen.sync`: SYNC timing (where each SYNC of the master's cycle falls);
- :mod:`~sim_table.canopen.history`: the recent leg lengths and accelerations SYNCs are answered from;
- :mod:`~sim_table.canopen.nodes`: the emulated nodes (leg drives, accelerometers, overturn detector);
- :mod:`~sim_table.canopen.counters`: what the endpoint counts;
- :mod:`~sim_table.canopen.endpoint`: the endpoint that runs them on the bus for the controller core, and
  ``open_endpoint`` (its behaviour is that module's docstring).

:mod:`sim_table.canopen_endpoint` is the import surface (``sim_table.endpoint`` opens it by name).
"""
