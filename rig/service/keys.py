"""The rig service's zenoh keys: the queryables of its control plane, its telemetry and its liveliness token.

They are the keys of :mod:`protocols.zenoh.keys` for one rig name (default :data:`DEFAULT_RIG`)::

    shaketable/<rig>/service/start     queryable   start a sequence (signed)
    shaketable/<rig>/service/pause     queryable   pause at the end of the current record
    shaketable/<rig>/service/resume    queryable   continue after a pause (signed)
    shaketable/<rig>/service/abort     queryable   controlled stop now (the run logged ``aborted``)
    shaketable/<rig>/service/estop     queryable   emergency stop (brake)
    shaketable/<rig>/service/state     queryable   the current progress and session path
    shaketable/<rig>/service/queue     queryable   queue a session, started later by ``start`` (signed)
    shaketable/<rig>/service/answer    queryable   answer the operator's prompt of an attended session (signed)
    shaketable/<rig>/telemetry/status  publication the progress (STATUS payload), ≤ 10 Hz and on every state change
    shaketable/<rig>/telemetry/run     publication a run's outcome (RUN payload) when it is known
    shaketable/<rig>/alive/service     liveliness  present while ``rig serve`` runs
"""

from __future__ import annotations

from typing import NamedTuple

from protocols.zenoh import SERVICE_COMMANDS, alive_key, service_key, telemetry_key

DEFAULT_RIG = "rig"
"""The rig's name in the key space when none is given."""

SIGNED_COMMANDS = frozenset({"start", "resume", "queue", "answer"})
"""Commands that make the table move (or line up a session that will): accepted only when signed with the rig's key
(``rig.service.server``). A client with the key signs the others too, so that the service can name it in its log."""

COMMANDS = SERVICE_COMMANDS
"""Every service command (``start``, ``pause``, ``resume``, ``abort``, ``estop``, ``state``, ``queue``, ``answer``)."""


class ServiceKeys(NamedTuple):
    """The keys of one rig's service (module docstring)."""

    rig: str
    commands: dict[str, str]
    status: str
    run: str
    alive: str

    @classmethod
    def for_rig(cls, rig: str = DEFAULT_RIG) -> ServiceKeys:
        """The keys of the rig named ``rig`` (a safe key chunk, :func:`protocols.zenoh.check_name`)."""
        return cls(rig, {command: service_key(rig, command) for command in SERVICE_COMMANDS},
                   telemetry_key(rig, "status"), telemetry_key(rig, "run"), alive_key(rig, "service"))
