"""Hardware-facing adapters behind small interfaces: the table controller, DAQ and overturn detectors.

May import ``protocols``; never ``rig``. Populated by the transports issue.
"""
