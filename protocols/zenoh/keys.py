"""zenoh key expressions of the rig service (control plane, telemetry, liveliness) and of the table link.

Every key starts with ``shaketable/<rig>/``; the rig's name tells apart several rigs on one zenoh network. The
table link (``drivers.zenoh`` ↔ the table controller, ``sim_table.zenoh_endpoint``) uses the ``controller`` plane
of the table's name (``zenoh://HOST:PORT/<table>``); its payloads are :mod:`protocols.zenoh.table`.

==========================================  ===============  =============================================
key                                         zenoh entity     payload (:mod:`protocols.zenoh.payloads`)
==========================================  ===============  =============================================
``shaketable/<rig>/service/<command>``      queryable        query: CONTROL_REQUEST, reply: CONTROL_REPLY
``shaketable/<rig>/telemetry/status``       publication      STATUS
``shaketable/<rig>/telemetry/accel/<s>``    publication      ACCEL (one key per accelerometer ``<s>``)
``shaketable/<rig>/telemetry/detection``    publication      DETECTION
``shaketable/<rig>/telemetry/run``          publication      RUN
``shaketable/<rig>/alive/<role>``           liveliness token none (the token's presence is the message)
==========================================  ===============  =============================================

Commands: ``start``, ``pause``, ``resume``, ``abort``, ``estop``, ``state`` (only asks), ``queue`` (a session to
start later), ``answer`` (an operator's prompt). Names (rig or table, sensor, role) are 1..32 characters from
``a-z``, ``0-9``, ``-`` and ``_``, starting with a letter or digit: safe in a key expression (no ``/``, ``*``, ``$``,
``?``, ``#``) and in file names. In the table link, the queryables and the publications without "host's" are the
controller's:

==============================================  ==================  ===========================================
table link key                                  zenoh entity        payload (:mod:`protocols.zenoh.table`)
==============================================  ==================  ===========================================
``shaketable/<t>/controller/command``           queryable           query: COMMAND (signed), reply: ANSWER
``shaketable/<t>/controller/clock``             queryable           query: CLOCK_REQUEST, reply: CLOCK_REPLY
``shaketable/<t>/controller/bodies``            queryable           query: none, reply: BODIES
``shaketable/<t>/controller/setpoints``         host's publication  SETPOINTS (signed)
``shaketable/<t>/controller/host-heartbeat``    host's publication  HEARTBEAT (host monotonic time)
``shaketable/<t>/controller/answer``            publication         ANSWER (final answers of HOME, SET_TILT)
``shaketable/<t>/controller/status``            publication         STATUS
``shaketable/<t>/controller/accel/<s>``         publication         ACCEL (one key per accelerometer ``<s>``)
``shaketable/<t>/controller/overturn``          publication         OVERTURN
``shaketable/<t>/controller/refusal``           publication         REFUSAL (a setpoint chunk refused, and why)
``shaketable/<t>/controller/tilt``              publication         TILT (every body's, the body in the payload)
``shaketable/<t>/controller/heartbeat``         publication         HEARTBEAT (controller time)
==============================================  ==================  ===========================================
"""

from __future__ import annotations

import re
from typing import NamedTuple

ROOT = "shaketable"
"""First chunk of every key."""

SERVICE_COMMANDS = ("start", "pause", "resume", "abort", "estop", "state", "queue", "answer")
"""Last chunk of the service queryables' keys."""

TELEMETRY_KINDS = ("status", "accel", "detection", "run")
"""Telemetry publications (``accel`` has one more chunk: the sensor)."""

TABLE_KINDS = ("command", "clock", "setpoints", "host-heartbeat", "answer", "status", "accel", "overturn",
               "heartbeat", "tilt", "bodies", "refusal", "limit-trip")
"""Keys of the table link (``accel`` has one more chunk: the sensor)."""

PLANES = ("service", "telemetry", "alive", "controller")
"""Second chunk after the rig's name."""

_NAME = re.compile(r"[a-z0-9][a-z0-9_-]{0,31}")


class KeyExprError(ValueError):
    """A name or key that is not one of the rig's key expressions."""


class Key(NamedTuple):
    """A parsed key: rig name, plane (``service``/``telemetry``/``alive``/``controller``), name (command, telemetry
    or table kind, or role), and the accelerometer's name for ``telemetry/accel/<sensor>`` and
    ``controller/accel/<sensor>`` (else ``None``)."""

    rig: str
    plane: str
    name: str
    sensor: str | None = None


def check_name(name: str, what: str = "name") -> str:
    """``name`` if it is a safe key chunk (see the module docstring), else :class:`KeyExprError`."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise KeyExprError(f"{what} {name!r} is not valid: use 1..32 characters from a-z, 0-9, '-' and '_', "
                           f"starting with a letter or digit")
    return name


def _one_of(value: str, allowed: tuple[str, ...], what: str) -> str:
    if value not in allowed:
        raise KeyExprError(f"unknown {what} {value!r}; expected one of {', '.join(allowed)}")
    return value


def service_key(rig: str, command: str) -> str:
    """Key of the queryable that carries ``command``."""
    return f"{ROOT}/{check_name(rig, 'rig name')}/service/{_one_of(command, SERVICE_COMMANDS, 'service command')}"


def telemetry_key(rig: str, kind: str, sensor: str | None = None) -> str:
    """Key of a telemetry publication; ``sensor`` names the accelerometer of ``accel`` (and only of it)."""
    key = f"{ROOT}/{check_name(rig, 'rig name')}/telemetry/{_one_of(kind, TELEMETRY_KINDS, 'telemetry kind')}"
    if kind == "accel":
        if sensor is None:
            raise KeyExprError("telemetry kind 'accel' needs a sensor name")
        return f"{key}/{check_name(sensor, 'sensor name')}"
    if sensor is not None:
        raise KeyExprError(f"telemetry kind {kind!r} takes no sensor name, got {sensor!r}")
    return key


def table_key(table: str, kind: str, sensor: str | None = None) -> str:
    """Key of the table link's ``kind`` (:data:`TABLE_KINDS`) for the table named ``table``; ``sensor`` names the
    accelerometer of ``accel`` (and only of it)."""
    key = f"{ROOT}/{check_name(table, 'table name')}/controller/{_one_of(kind, TABLE_KINDS, 'table kind')}"
    if kind == "accel":
        if sensor is None:
            raise KeyExprError("table kind 'accel' needs a sensor name")
        return f"{key}/{check_name(sensor, 'sensor name')}"
    if sensor is not None:
        raise KeyExprError(f"table kind {kind!r} takes no sensor name, got {sensor!r}")
    return key


def table_accel_selector(table: str) -> str:
    """Key expression of every accelerometer's ``accel`` key of the table named ``table``."""
    return f"{ROOT}/{check_name(table, 'table name')}/controller/accel/*"


def alive_key(rig: str, role: str) -> str:
    """Key of the liveliness token of a process in ``role`` (e.g. ``service``, ``emulator``) on ``rig``."""
    return f"{ROOT}/{check_name(rig, 'rig name')}/alive/{check_name(role, 'role')}"


def service_selector(rig: str) -> str:
    """Key expression of all of a rig's service queryables (what the service declares)."""
    return f"{ROOT}/{check_name(rig, 'rig name')}/service/*"


def telemetry_selector(rig: str) -> str:
    """Key expression of all of a rig's telemetry (what a monitor subscribes to)."""
    return f"{ROOT}/{check_name(rig, 'rig name')}/telemetry/**"


def alive_selector(rig: str | None = None) -> str:
    """Key expression of the liveliness tokens of ``rig``, or of every rig when ``None``."""
    return f"{ROOT}/{'*' if rig is None else check_name(rig, 'rig name')}/alive/*"


def parse_key(key: str) -> Key:
    """The parts of one of the rig's keys (as built by the functions above); :class:`KeyExprError` otherwise."""
    chunks = str(key).split("/")
    if len(chunks) < 4 or chunks[0] != ROOT:
        raise KeyExprError(f"key {key!r} is not a rig key: expected {ROOT}/<rig>/<plane>/<name>[/<sensor>]")
    rig, plane, name, rest = check_name(chunks[1], "rig name"), chunks[2], chunks[3], chunks[4:]
    _one_of(plane, PLANES, "plane")
    if plane == "service":
        _one_of(name, SERVICE_COMMANDS, "service command")
    elif plane == "telemetry":
        _one_of(name, TELEMETRY_KINDS, "telemetry kind")
    elif plane == "controller":
        _one_of(name, TABLE_KINDS, "table kind")
    else:
        check_name(name, "role")
    accel = plane in ("telemetry", "controller") and name == "accel"
    if len(rest) != int(accel):
        raise KeyExprError(f"key {key!r} has {len(chunks)} chunks; {plane}/{name} keys have {4 + int(accel)}")
    return Key(rig, plane, name, check_name(rest[0], "sensor name") if accel else None)
