"""The table controller's errors: :class:`TableError` and the refusals, timeouts and losses derived from it.

Every command of :class:`~drivers.interface.TableController` raises one of these when the controller refused or
failed (``docs/table-controller.md``); :mod:`drivers.controller` re-exports them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drivers.feedback import StreamReport


class TableError(Exception):
    """Anything the table controller refused or failed to do; the message says what and in which state."""


class TableTimeoutError(TableError):
    """No answer from the controller in time (after the retries)."""


class CommandRefusedError(TableError):
    """The controller answered a command with a refusal: ``command`` (name), ``result`` (name), ``state``."""

    def __init__(self, command: str, result: str, state: str | None, why: str) -> None:
        self.command = command
        self.result = result
        self.state = state
        where = f" (table {state})" if state else ""
        super().__init__(f"{command} refused: {why}{where}")


class CommandDeniedError(CommandRefusedError):
    """Refused for a missing or bad signature (the signing key of host and controller differ)."""


class CommandRejectedError(CommandRefusedError):
    """Refused because the controller's state does not accept the command now."""


class CommandFailedError(CommandRefusedError):
    """Refused for invalid parameters, unsupported, or a motion that was cancelled before its end."""


class TableInUseError(TableError):
    """Another host owns the table (``docs/table-controller.md``, One host at a time): :meth:`TableController.connect`
    refused, the message naming the owner and since when."""


class TableLinkLostError(TableError):
    """No status from the controller for longer than the link timeout: the link, or the controller, is gone."""


class SetpointError(TableError, ValueError):
    """A trajectory the table must not play (``analysis.table.setpoints``: a sample not finite, outside the envelope
    or a leg's stroke, a step beyond the leg speed or tilt rate): refused by the host before anything is sent. A
    ValueError too, as the bad arguments of :meth:`TableController.stream` it replaces."""


class StreamAbortedError(TableError):
    """The controller stopped playing a stream before its end; ``report`` says how far it got."""

    def __init__(self, message: str, report: StreamReport) -> None:
        self.report = report
        super().__init__(message)
