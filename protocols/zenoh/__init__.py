"""zenoh wire formats of the rig service (the lab-side bus).

- :mod:`~protocols.zenoh.keys` — key expressions ``shaketable/<rig>/{service,telemetry,alive,controller}/...``
- :mod:`~protocols.zenoh.payloads` — versioned payloads (8-byte header; JSON bodies, binary accelerometer batches)
- :mod:`~protocols.zenoh.config` — ``session_config``: explicit endpoints, mutual TLS off loopback, scouting off
- :mod:`~protocols.zenoh.tls` — a process's TLS identity (CA, certificate, key) checked, and why a TLS link fails
- :mod:`~protocols.zenoh.table` — the table link (``zenoh://HOST:PORT/TABLE``): its URL and binary payloads
- :mod:`~protocols.zenoh.auth` — HMAC-SHA256 signatures of every payload of the table link
"""

from protocols.zenoh.config import EndpointError, LinkSecurity, check_endpoint, loopback_endpoint, session_config
from protocols.zenoh.keys import (
    ROOT,
    SERVICE_COMMANDS,
    TABLE_KINDS,
    TELEMETRY_KINDS,
    Key,
    KeyExprError,
    alive_key,
    alive_selector,
    check_name,
    parse_key,
    service_key,
    service_selector,
    table_accel_selector,
    table_key,
    telemetry_key,
    telemetry_selector,
)
from protocols.zenoh.payloads import (
    MAGIC,
    REQUIRED_FIELDS,
    TELEMETRY_PAYLOADS,
    VERSION,
    AccelBatch,
    Kind,
    PayloadError,
    decode_accel,
    decode_json,
    encode_accel,
    encode_json,
    read_header,
)

__all__ = [
    "MAGIC",
    "REQUIRED_FIELDS",
    "ROOT",
    "SERVICE_COMMANDS",
    "TABLE_KINDS",
    "TELEMETRY_KINDS",
    "TELEMETRY_PAYLOADS",
    "VERSION",
    "AccelBatch",
    "EndpointError",
    "Key",
    "KeyExprError",
    "Kind",
    "LinkSecurity",
    "PayloadError",
    "alive_key",
    "alive_selector",
    "check_endpoint",
    "check_name",
    "decode_accel",
    "decode_json",
    "encode_accel",
    "encode_json",
    "loopback_endpoint",
    "parse_key",
    "read_header",
    "service_key",
    "service_selector",
    "session_config",
    "table_accel_selector",
    "table_key",
    "telemetry_key",
    "telemetry_selector",
]
