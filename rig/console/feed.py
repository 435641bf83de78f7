"""The console's data path: the rig service's zenoh telemetry (``telemetry/status`` and ``telemetry/live``), the
service's own publications — the console has no other path to the table."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

import zenoh

from protocols.zenoh import LinkSecurity, session_config
from protocols.zenoh.config import PLAIN
from protocols.zenoh.payloads import Kind, PayloadError, decode_json
from rig.service.keys import DEFAULT_RIG, ServiceKeys
from rig.service.telemetry import live_key


class TelemetrySubscription:
    """Subscribes to the service at ``connect`` (``tcp/127.0.0.1:7447``) and calls ``deliver(kind, body)``
    (``kind`` ``"status"`` or ``"live"``) from zenoh's threads for every publication; payloads that are not the
    service's are ignored (``security``: the zenoh link's TLS identity). ``deliver`` must not block (the console
    hands it to its event loop)."""

    def __init__(self, connect: str, deliver: Callable[[str, dict[str, Any]], None], rig: str = DEFAULT_RIG,
                 security: LinkSecurity = PLAIN) -> None:
        keys = ServiceKeys.for_rig(rig)
        self._deliver = deliver
        self._session = zenoh.open(session_config(connect=[connect], security=security))
        self._subscribers = [self._session.declare_subscriber(keys.status, lambda s: self._on(s, "status")),
                             self._session.declare_subscriber(live_key(keys), lambda s: self._on(s, "live"))]

    def _on(self, sample: zenoh.Sample, kind: str) -> None:
        with contextlib.suppress(PayloadError):
            self._deliver(kind, decode_json(sample.payload.to_bytes(), Kind.STATUS))

    def close(self) -> None:
        with contextlib.suppress(zenoh.ZError):
            for subscriber in self._subscribers:
                subscriber.undeclare()
            self._session.close()
