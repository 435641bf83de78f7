"""The project's MAVLink 2 dialect (``shaketable.xml``) and what the table link needs around it.

- :mod:`~protocols.mavlink.codegen`: generates the dialect's Python code with pymavlink's mavgen on first use
  (cached per user, never committed) and imports it: :func:`dialect`.
- :mod:`~protocols.mavlink.framing`: setpoint arrays (N, 6) ↔ SHAKETABLE_SETPOINT_CHUNK messages, accelerometer
  arrays (N, 3) ↔ SHAKETABLE_ACCEL_BATCH messages, a body's tilt angles (N,) ↔ SHAKETABLE_TILT_BATCH messages.
- :mod:`~protocols.mavlink.signing`: MAVLink 2 signing on a link (the rig's key: :mod:`protocols.signing_key`), which
  messages need it.
- :mod:`~protocols.mavlink.link`: a UDP endpoint speaking the dialect (:class:`UdpLink`), or pymavlink's mavutil
  with it (:func:`mavlink_connection`).

Messages (ids 42500–42509 reserved): SHAKETABLE_SETPOINT_CHUNK (42500), SHAKETABLE_ACCEL_BATCH (42501),
SHAKETABLE_OVERTURN_EVENT (42502), SHAKETABLE_STATUS (42503), SHAKETABLE_TILT_BATCH (42504), SHAKETABLE_BODY
(42505), SHAKETABLE_CHUNK_REFUSED (42506), SHAKETABLE_OWNER (42507); commands in COMMAND_LONG (MAV_CMD
42550–42559 reserved): MAV_CMD_SHAKETABLE_ARM, _DISARM, _HOME, _SET_TILT, _START_STREAM, _STOP, _EMERGENCY_STOP,
_CLAIM, _RELEASE. Units and field meanings are in the XML. Importing this package generates nothing; the first
:func:`dialect` call does.
"""

from protocols.mavlink.codegen import DIALECT_NAME, DialectError, dialect
from protocols.mavlink.framing import (
    ACCEL_PER_BATCH,
    END_OF_STREAM,
    SETPOINTS_PER_CHUNK,
    TILT_PER_BATCH,
    FramingError,
    SequenceGapError,
    Series,
    accel_batches,
    join_accel_batches,
    join_setpoint_chunks,
    setpoint_chunks,
    tilt_batches,
    unpack_accel_batch,
    unpack_setpoint_chunk,
    unpack_tilt_batch,
)
from protocols.mavlink.link import UdpLink, mavlink_connection, whole_frames
from protocols.mavlink.signing import (
    REPLAY_WINDOW,
    STAMP_AHEAD,
    badly_signed,
    enable_signing,
    follow_wall_clock,
    parse_guarded,
    parse_verified,
    replay_guard,
    requires_signature,
    signed_with_key,
)

__all__ = [
    "ACCEL_PER_BATCH",
    "DIALECT_NAME",
    "END_OF_STREAM",
    "REPLAY_WINDOW",
    "SETPOINTS_PER_CHUNK",
    "STAMP_AHEAD",
    "TILT_PER_BATCH",
    "DialectError",
    "FramingError",
    "SequenceGapError",
    "Series",
    "UdpLink",
    "accel_batches",
    "badly_signed",
    "dialect",
    "enable_signing",
    "follow_wall_clock",
    "join_accel_batches",
    "join_setpoint_chunks",
    "mavlink_connection",
    "parse_guarded",
    "parse_verified",
    "replay_guard",
    "requires_signature",
    "setpoint_chunks",
    "signed_with_key",
    "tilt_batches",
    "unpack_accel_batch",
    "unpack_setpoint_chunk",
    "unpack_tilt_batch",
    "whole_frames",
]
