"""The emulator's CANopen side (``canopen://CHANNEL?interface=NAME``): the import surface of
:mod:`sim_table.canopen`, where each job has its module — the endpoint and what it does on the bus is
:mod:`sim_table.canopen.endpoint`. Every name this module defined before the cut is re-exported here.
"""

from __future__ import annotations

from sim_table.canopen.bus import SYNC_COB_ID, StampingVirtualBus
from sim_table.canopen.counters import BusCounters
from sim_table.canopen.endpoint import BACKLOG_LIMIT, CanopenEndpoint, open_endpoint
from sim_table.canopen.history import HISTORY, Recent
from sim_table.canopen.nodes import FEEDBACK_DELAY, TARGET_DELAY, TARGET_DELAY_RANGE
from sim_table.canopen.sync import DRIFT, SERIES_GAP, SyncGrid

__all__ = [
    "BACKLOG_LIMIT",
    "DRIFT",
    "FEEDBACK_DELAY",
    "HISTORY",
    "SERIES_GAP",
    "SYNC_COB_ID",
    "TARGET_DELAY",
    "TARGET_DELAY_RANGE",
    "BusCounters",
    "CanopenEndpoint",
    "Recent",
    "StampingVirtualBus",
    "SyncGrid",
    "open_endpoint",
]
