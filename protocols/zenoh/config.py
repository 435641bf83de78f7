"""zenoh session configuration of the rig's processes: explicit endpoints, TLS off loopback, no scouting.

A zenoh 1.x peer's defaults listen on every interface (``tcp/[::]:0``) and scout by UDP multicast
(224.0.0.224:7446) and gossip. The rig's processes find each other only through the endpoints they are given:
:func:`session_config` sets ``mode = "peer"``, the listen and connect endpoints (explicit addresses and ports) and
turns multicast and gossip scouting off.

**Across hosts** (``docs/lab-network.md``) a link is ``tls/ADDRESS:PORT`` with mutual authentication: the session's
:class:`LinkSecurity` carries the process's TLS identity (:mod:`protocols.zenoh.tls`: the lab's CA, its certificate
and key), zenoh is told to present that certificate on both sides of every link, to accept only peers the CA signed,
to check the listener's certificate names the address connected to, to close a link when a certificate expires, and
to open no link of another protocol. A plain ``tcp/``/``udp/`` endpoint must be on loopback unless the session is
explicitly ``insecure`` (``--insecure-plain-tcp``: the caller says so in its log and the session's events).

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
from typing import NamedTuple

import zenoh

from protocols.zenoh.tls import TlsFiles

_ENDPOINT = re.compile(r"(?P<protocol>tcp|udp|tls)/(?:\[(?P<ipv6>[0-9a-fA-F:]+)\]|(?P<ipv4>[0-9.]+))"
                       r":(?P<port>[0-9]{1,5})")


TX_QUEUE_BATCHES = 16
"""Batches (64 KiB each, allocated as needed) in a session's transmit queue for the data priority (module
docstring; zenoh's default is 2, its largest 16)."""


class EndpointError(ValueError):
    """An endpoint that is not an explicit address and port, plain text off loopback without ``insecure``, TLS
    without an identity, or a session that would reach nobody."""


class LinkSecurity(NamedTuple):
    """How a session's links are protected: ``tls`` the process's TLS identity (None: plain links, loopback only),
    ``insecure`` True to allow plain ``tcp/``/``udp/`` endpoints off loopback (nothing encrypted: a bench network
    only, said in the log)."""

    tls: TlsFiles | None = None
    insecure: bool = False

    @property
    def protocol(self) -> str:
        """``tls`` with an identity, else ``tcp``: the protocol of an endpoint made from an address and a port."""
        return "tls" if self.tls is not None else "tcp"

    def endpoint(self, host: str, port: int) -> str:
        """``PROTOCOL/HOST:PORT`` (``[HOST]`` for IPv6) in :attr:`protocol`, checked (:func:`check_endpoint`)."""
        address = f"[{host}]" if ":" in host else host
        return check_endpoint(f"{self.protocol}/{address}:{port}", insecure=self.insecure)


PLAIN = LinkSecurity()
"""Plain links on loopback: the rig's processes on one host."""


def loopback_endpoint(port: int, protocol: str = "tcp") -> str:
    """``tcp/127.0.0.1:<port>`` (or ``udp/...``), checked as :func:`session_config` checks endpoints."""
    return check_endpoint(f"{protocol}/127.0.0.1:{port}")


def check_endpoint(endpoint: str, *, insecure: bool = False) -> str:
    """``endpoint`` if it is ``tcp|udp|tls/<IP address>:<port 1..65535>``, a plain ``tcp``/``udp`` one on loopback
    unless ``insecure``; else :class:`EndpointError`."""
    match = _ENDPOINT.fullmatch(endpoint) if isinstance(endpoint, str) else None
    if match is None:
        raise EndpointError(f"endpoint {endpoint!r} is not of the form tls/ADDRESS:PORT, tcp/127.0.0.1:PORT, "
                            f"tcp/[::1]:PORT (or udp/...)")
    try:
        address = ipaddress.ip_address(match["ipv6"] or match["ipv4"])
    except ValueError:
        raise EndpointError(f"endpoint {endpoint!r} has no valid IP address") from None
    if not 1 <= int(match["port"]) <= 65535:
        raise EndpointError(f"endpoint {endpoint!r} needs an explicit port in 1..65535")
    if match["protocol"] != "tls" and not address.is_loopback and not insecure:
        host = f"[{address}]" if address.version == 6 else str(address)
        raise EndpointError(f"endpoint {endpoint!r} is off loopback and not encrypted: use tls/{host}:{match['port']} "
                            "with a TLS identity (--tls-ca, --tls-cert, --tls-key; docs/lab-network.md), or allow "
                            "plain text explicitly with --insecure-plain-tcp")
    return endpoint


def session_config(listen: Sequence[str] = (), connect: Sequence[str] = (),
                   security: LinkSecurity = PLAIN) -> zenoh.Config:
    """A peer ``zenoh.Config`` that listens on ``listen`` and connects to ``connect``, with scouting off, a
    transmit queue of :data:`TX_QUEUE_BATCHES` batches and, with ``security.tls``, mutual TLS on every link (module
    docstring)."""
    if isinstance(listen, str) or isinstance(connect, str):
        raise EndpointError("listen and connect take sequences of endpoints, not one string")
    listen = [check_endpoint(e, insecure=security.insecure) for e in listen]
    connect = [check_endpoint(e, insecure=security.insecure) for e in connect]
    if not listen and not connect:
        raise EndpointError("a session with neither listen nor connect endpoints reaches nobody (scouting is off)")
    for endpoint in (*listen, *connect):
        tls = endpoint.startswith("tls/")
        if tls and security.tls is None:
            raise EndpointError(f"endpoint {endpoint!r} is TLS but no TLS identity is given (--tls-ca, --tls-cert, "
                                "--tls-key)")
        if not tls and security.tls is not None:
            raise EndpointError(f"endpoint {endpoint!r} is plain text but a TLS identity is given: use "
                                f"tls/{endpoint.partition('/')[2]}")
    config = zenoh.Config()
    settings: list[tuple[str, object]] = [
        ("mode", "peer"), ("listen/endpoints", listen), ("connect/endpoints", connect),
        ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
        ("transport/link/tx/queue/size/data", TX_QUEUE_BATCHES)]
    if security.tls is not None:
        ca, certificate, key = (str(path.resolve()) for path in security.tls)
        settings += [("transport/link/protocols", ["tls"]),
                     ("transport/link/tls", {"root_ca_certificate": ca, "enable_mtls": True,
                                             "listen_certificate": certificate, "listen_private_key": key,
                                             "connect_certificate": certificate, "connect_private_key": key,
                                             "verify_name_on_connect": True, "close_link_on_expiration": True})]
    for key_path, value in settings:
        config.insert_json5(key_path, json.dumps(value))
    return config
