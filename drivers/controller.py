"""The table controller interface: one small API for every transport, backends chosen by a URL scheme.

Like python-can's ``Bus``: :func:`open_table` takes ``scheme://…`` and returns a :class:`TableController` of
the backend registered for that scheme (``mavlink://HOST:PORT`` → :mod:`drivers.mavlink`; other transports
register with :func:`register_scheme`). The behaviour every backend carries is ``docs/table-controller.md``.

This module is the import surface: every name is defined in one room and re-exported here, so that
``from drivers.controller import X`` works for all of them —

- :mod:`drivers.errors`: :class:`TableError` and its subclasses;
- :mod:`drivers.feedback`: what a controller reports (:class:`TableStatus`, :class:`AccelBatch`,
  :class:`TiltBatch`, :class:`Detection`, :class:`FaultEvent`, …) and :class:`StreamReport`;
- :mod:`drivers.hub`: the feedback hub (:class:`Feedback`) and its subscriptions (:class:`Subscription`);
- :mod:`drivers.interface`: :class:`TableController`, its constants and the helpers the backends share to stream;
- :mod:`drivers.registry`: :func:`open_table`, :func:`register_scheme`, :func:`host_port`.

Units and conventions (docs/architecture.md §2): SI; a pose is ``(surge, sway, heave [m], roll, pitch, yaw [rad])``
as in ``analysis.table.model``; tilt β > 0 is pitch = +β (+x downhill); time stamps are integer nanoseconds of
**controller time** (the controller's own monotonic clock) unless a name says ``host``. Overturn direction +1 is
towards the low side, −1 towards the high side.
"""

from __future__ import annotations

from analysis.table.link import LinkSettings
from analysis.table.model import TableModel
from analysis.table.setpoints import check_setpoints
from drivers.bodies import TableBody
from drivers.errors import (
    CommandDeniedError,
    CommandFailedError,
    CommandRefusedError,
    CommandRejectedError,
    SetpointError,
    StreamAbortedError,
    TableError,
    TableInUseError,
    TableLinkLostError,
    TableTimeoutError,
)
from drivers.feedback import (
    AccelBatch,
    ControllerText,
    Detection,
    FaultEvent,
    FaultSource,
    SetpointRefusal,
    StreamReport,
    TableStatus,
    TiltBatch,
)
from drivers.heap import HeapHold
from drivers.hub import Feedback, Subscription, T
from drivers.interface import (
    DEFAULT_LEAD,
    LINK_GRACE,
    STATUS_TIMEOUT,
    STOPPED_STATES,
    TILT_AXES,
    WAIT_SLICE,
    TableController,
    playable_poses,
    sample_spacing,
    sleep_until,
)
from drivers.registry import Factory, host_port, open_table, register_scheme

__all__ = [
    "DEFAULT_LEAD",
    "LINK_GRACE",
    "STATUS_TIMEOUT",
    "STOPPED_STATES",
    "TILT_AXES",
    "WAIT_SLICE",
    "AccelBatch",
    "CommandDeniedError",
    "CommandFailedError",
    "CommandRefusedError",
    "CommandRejectedError",
    "ControllerText",
    "Detection",
    "Factory",
    "FaultEvent",
    "FaultSource",
    "Feedback",
    "HeapHold",
    "LinkSettings",
    "SetpointError",
    "SetpointRefusal",
    "StreamAbortedError",
    "StreamReport",
    "Subscription",
    "T",
    "TableBody",
    "TableController",
    "TableError",
    "TableInUseError",
    "TableLinkLostError",
    "TableModel",
    "TableStatus",
    "TableTimeoutError",
    "TiltBatch",
    "check_setpoints",
    "host_port",
    "open_table",
    "playable_poses",
    "register_scheme",
    "sample_spacing",
    "sleep_until",
]
