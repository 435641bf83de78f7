"""Hardware-facing adapters behind small interfaces: the table controller, DAQ and overturn detectors.

May import ``protocols``; never ``rig``. :mod:`drivers.controller` is the table controller interface and its URL
registry (``open_table("mavlink://HOST:PORT", ...)``); :mod:`drivers.mavlink` the MAVLink 2 / UDP backend and
:mod:`drivers.zenoh` the zenoh one, both over :mod:`drivers.chunked` (their commands and chunked streaming);
:mod:`drivers.canopen` the CANopen master (a package: set-up, SYNC cycle, feedback, faults, motion).
"""

from drivers.controller import (
    AccelBatch,
    CommandDeniedError,
    CommandFailedError,
    CommandRefusedError,
    CommandRejectedError,
    Detection,
    FaultEvent,
    SetpointError,
    SetpointRefusal,
    StreamAbortedError,
    StreamReport,
    Subscription,
    TableController,
    TableError,
    TableInUseError,
    TableStatus,
    TableTimeoutError,
    TiltBatch,
    open_table,
    register_scheme,
)

__all__ = [
    "AccelBatch",
    "CommandDeniedError",
    "CommandFailedError",
    "CommandRefusedError",
    "CommandRejectedError",
    "Detection",
    "FaultEvent",
    "SetpointError",
    "SetpointRefusal",
    "StreamAbortedError",
    "StreamReport",
    "Subscription",
    "TableController",
    "TableError",
    "TableInUseError",
    "TableStatus",
    "TableTimeoutError",
    "TiltBatch",
    "open_table",
    "register_scheme",
]
