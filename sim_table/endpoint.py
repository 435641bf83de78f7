"""The emulator's transport endpoints: one small interface, implementations chosen by the listen URL's scheme.

An endpoint is the controller end of one transport (``mavlink://HOST:PORT`` → `sim_table.mavlink_endpoint`;
``canopen://…`` and ``zenoh://…`` register the same way). The emulator loop (`sim_table.process`) owns it:

- host messages arrive on the endpoint's own threads and wait in its inbox; :meth:`Endpoint.take` hands them
  over in arrival order as ``(arrival controller ns, action)`` pairs, each action applied to the
  `~sim_table.controller.ControllerCore` between ticks at its arrival time;
- the loop gives the endpoint what to send: final command answers (:meth:`Endpoint.command_done`), statuses,
  accelerometer samples, overturn events; :meth:`Endpoint.service` sends what is due (heartbeats, resends).

Behaviour on every transport: ``docs/table-controller.md``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable
from urllib.parse import urlsplit

import numpy as np

from analysis.table.model import TableModel
from sim_table.controller import ControllerCore, Done, Snapshot, State

Action = Callable[[ControllerCore], None]
"""A host message as an effect on the controller core."""

#: Listen-URL scheme → module providing ``open_endpoint(url, options)``.
ENDPOINT_MODULES: dict[str, str] = {
    "mavlink": "sim_table.mavlink_endpoint",
    "canopen": "sim_table.canopen_endpoint",
    "zenoh": "sim_table.zenoh_endpoint",
}


@dataclass(frozen=True)
class EndpointOptions:
    """What every endpoint is built with.

    ``key`` the 32-byte secret that authenticates motion commands and setpoints; ``clock`` maps host monotonic
    ns to controller ns; ``table`` the table model (leg scaling on CANopen); ``loss`` (probability) and
    ``delay`` [s] inject faults on every message both ways with ``seed``; ``virtual_time``: the controller's clock
    is virtual (``--speed max``), so it may wait for the link rather than drop telemetry.
    """

    key: bytes = field(repr=False)
    clock: Callable[[int], int]
    table: TableModel
    loss: float = 0.0
    delay: float = 0.0
    seed: int = 0
    virtual_time: bool = False


class Endpoint(Protocol):
    """The controller end of one transport (module docstring)."""

    url: str
    """The URL it listens on, ports resolved (``mavlink://127.0.0.1:0`` → the port it got)."""
    stall_chunks: bool
    """Set by the owner to drop every setpoint chunk from then on (injected stalled stream)."""

    def start(self) -> None: ...
    def take(self, now: int) -> list[tuple[int, Action]]: ...
    def command_done(self, done: Done) -> None: ...
    def send_status(self, snap: Snapshot) -> None: ...
    def add_accel(self, sensor_id: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> None: ...
    def flush_accel(self) -> None: ...
    def send_overturn(self, event_id: int, body_id: int, direction: int, tilt: float, t_ns: int) -> None: ...
    def service(self, now: int, state: State) -> None: ...
    def close(self) -> None: ...
    def counters_dict(self) -> dict[str, Any]: ...


@runtime_checkable
class LegFeedback(Protocol):
    """An endpoint whose drives report each leg's measured length (CANopen: at every SYNC) and watch its following
    error: the loop gives it the legs' true and commanded lengths of every tick."""

    def add_legs(self, t_start_ns: int, spacing_ns: int, lengths: np.ndarray, commanded: np.ndarray) -> None: ...


@runtime_checkable
class HeldAnswers(Protocol):
    """An endpoint whose command answers carry no controller time (MAVLink's COMMAND_ACK): it holds the answers
    given during a batch and sends them when the loop says, after the batch's statuses, so that the host receives
    the status showing what a command did before its answer, and a status taken after it next."""

    def send_answers(self) -> bool: ...


def listen_scheme(url: str) -> str:
    """The scheme of a listen URL, checked against the known endpoints (ValueError names the choices)."""
    scheme = urlsplit(url).scheme
    if scheme not in ENDPOINT_MODULES:
        choices = ", ".join(f"{s}://…" for s in ENDPOINT_MODULES)
        raise ValueError(f"--listen {url!r}: the emulator listens on {choices}")
    return scheme


def open_endpoint(url: str, options: EndpointOptions) -> Endpoint:
    """The endpoint for ``url`` (its module imported on first use)."""
    module = importlib.import_module(ENDPOINT_MODULES[listen_scheme(url)])
    return module.open_endpoint(url, options)
