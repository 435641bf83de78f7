"""zenoh session configuration of the rig's processes: explicit loopback endpoints, no scouting.

A zenoh 1.x peer's defaults listen on every interface (``tcp/[::]:0``) and scout by UDP multicast
(224.0.0.224:7446) and gossip. The rig's processes run on one host and find each other only through the
endpoints they are given: :func:`session_config` sets ``mode = "peer"``, the listen and connect endpoints
(loopback ``tcp``/``udp`` only, explicit ports) and turns multicast and gossip scouting off.

It also deepens the transmit queue of the data priority (every rig message's) from zenoh's 2 batches to
:data:`TX_QUEUE_BATCHES`. An express message (statuses, answers, heartbeats) takes a batch of its own until the
session's transmit thread has written it, and a message under zenoh's default congestion control is dropped when no
batch comes free within 1 ms. A table controller that catches up after its process was held off the CPU sends a
few statuses and a heartbeat at once, then its accelerometer and tilt batches: with 2 batches those were dropped
whenever the transmit thread itself took longer than 1 ms to run — on a 2-core host busy with a test suite, one
50 ms batch of every sensor in about one whole 42 s drive of two (docs/notes/2026-11-27-real-time.md).
"""

from __future__ import annotations

import ipaddress
import json
import re
from collections.abc import Sequence

import zenoh

_ENDPOINT = re.compile(r"(?P<protocol>tcp|udp)/(?:\[(?P<ipv6>[0-9a-fA-F:]+)\]|(?P<ipv4>[0-9.]+)):(?P<port>[0-9]{1,5})")


TX_QUEUE_BATCHES = 16
"""Batches (64 KiB each, allocated as needed) in a session's transmit queue for the data priority (module
docstring; zenoh's default is 2, its largest 16)."""


class EndpointError(ValueError):
    """An endpoint that is not an explicit loopback endpoint, or a session that would reach nobody."""


def loopback_endpoint(port: int, protocol: str = "tcp") -> str:
    """``tcp/127.0.0.1:<port>`` (or ``udp/...``), checked as :func:`session_config` checks endpoints."""
    return check_endpoint(f"{protocol}/127.0.0.1:{port}")


def check_endpoint(endpoint: str) -> str:
    """``endpoint`` if it is ``tcp|udp/<loopback address>:<port 1..65535>``, else :class:`EndpointError`."""
    match = _ENDPOINT.fullmatch(endpoint) if isinstance(endpoint, str) else None
    if match is None:
        raise EndpointError(f"endpoint {endpoint!r} is not of the form tcp/127.0.0.1:PORT, tcp/[::1]:PORT "
                            f"(or udp/...)")
    try:
        address = ipaddress.ip_address(match["ipv6"] or match["ipv4"])
    except ValueError:
        raise EndpointError(f"endpoint {endpoint!r} has no valid IP address") from None
    if not address.is_loopback:
        raise EndpointError(f"endpoint {endpoint!r} is not on loopback (127.0.0.0/8 or ::1)")
    if not 1 <= int(match["port"]) <= 65535:
        raise EndpointError(f"endpoint {endpoint!r} needs an explicit port in 1..65535")
    return endpoint


def session_config(listen: Sequence[str] = (), connect: Sequence[str] = ()) -> zenoh.Config:
    """A peer ``zenoh.Config`` that listens on ``listen`` and connects to ``connect``, with scouting off and a
    transmit queue of :data:`TX_QUEUE_BATCHES` batches."""
    if isinstance(listen, str) or isinstance(connect, str):
        raise EndpointError("listen and connect take sequences of endpoints, not one string")
    listen, connect = [check_endpoint(e) for e in listen], [check_endpoint(e) for e in connect]
    if not listen and not connect:
        raise EndpointError("a session with neither listen nor connect endpoints reaches nobody (scouting is off)")
    config = zenoh.Config()
    for key, value in (("mode", "peer"), ("listen/endpoints", listen), ("connect/endpoints", connect),
                       ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
                       ("transport/link/tx/queue/size/data", TX_QUEUE_BATCHES)):
        config.insert_json5(key, json.dumps(value))
    return config
