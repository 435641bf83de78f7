"""The rig service: the orchestrator run by ``rig serve`` with zenoh as its control plane, and its clients.

- :mod:`~rig.service.keys` — the queryables, telemetry publications and liveliness token
- :mod:`~rig.service.wire` — requests, replies, signatures and the service's errors
- :mod:`~rig.service.server` — :class:`OrchestratorService` (one session at a time, in a worker thread)
- :mod:`~rig.service.session` — the ``start`` request and the session's worker
- :mod:`~rig.service.operator` — the operator of an attended session, answered by the ``answer`` command
- :mod:`~rig.service.audit` — a control request's source as the transport vouches for it, escaped
- :mod:`~rig.service.telemetry` — the throttled status publications
- :mod:`~rig.service.client` — :class:`ServiceClient` and its :class:`TelemetryFeed`
"""

from rig.service.client import ServiceClient, TelemetryFeed
from rig.service.keys import DEFAULT_RIG, SIGNED_COMMANDS, ServiceKeys
from rig.service.server import OrchestratorService
from rig.service.session import StartRequest
from rig.service.wire import ServiceError, ServiceUnavailableError

__all__ = ["DEFAULT_RIG", "SIGNED_COMMANDS", "OrchestratorService", "ServiceClient", "ServiceError", "ServiceKeys",
           "ServiceUnavailableError", "StartRequest", "TelemetryFeed"]
