"""The emulator's transport endpoints: one small interface, implementations chosen by the listen URL's scheme.

An endpoint is the controller end of one transport (``mavlink://HOST:PORT`` → `sim_table.mavlink_endpoint`;
``canopen://…`` and ``zenoh://…`` register the same way). The emulator loop (`sim_table.process`) owns it:

- host messages arrive on the endpoint's own threads and wait in its inbox; :meth:`Endpoint.take` hands them
  over in arrival order as ``(arrival controller ns, action)`` pairs, each action applied to the
  `~sim_table.controller.ControllerCore` between ticks at its arrival time;
- the loop gives the endpoint what to send: final command answers (:meth:`Endpoint.command_done`), the reason a
  setpoint chunk was refused (:meth:`Endpoint.chunk_refused`), statuses,
  accelerometer samples, the bodies' tilt samples, overturn events; :meth:`Endpoint.service` sends what is due
  (heartbeats, resends). Evenly spaced samples (accelerometers, tilts) come in pieces that continue each other in
  time; an endpoint that sends them in batches gathers them with a :class:`Batcher`.

Behaviour on every transport: ``docs/table-controller.md``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Protocol, runtime_checkable
from urllib.parse import urlsplit

import numpy as np

from analysis.table.controller_limits import ControllerTrip
from analysis.table.model import TableModel
from protocols.zenoh.config import PLAIN, LinkSecurity
from sim_table.controller import ControllerCore, Done, Refused, Snapshot, State

Action = Callable[[ControllerCore], object]
"""A host message as an effect on the controller core (what it returns is not used)."""

#: Listen-URL scheme → module providing ``open_endpoint(url, options)``.
ENDPOINT_MODULES: dict[str, str] = {
    "mavlink": "sim_table.mavlink_endpoint",
    "canopen": "sim_table.canopen_endpoint",
    "zenoh": "sim_table.zenoh_endpoint",
}


class BodyOnPlate(NamedTuple):
    """A specimen as the controller reports it (``docs/table-controller.md``, Bodies on the plate): breadth ``b``
    along x, height ``h``, ``depth`` along y and the centre of its base at (``x``, ``y``) on the plate [m]."""

    b: float
    h: float
    depth: float
    x: float
    y: float


@dataclass(frozen=True)
class EndpointOptions:
    """What every endpoint is built with.

    ``key`` the 32-byte secret that authenticates motion commands and setpoints; ``clock`` maps host monotonic
    ns to controller ns; ``table`` the table model (leg scaling on CANopen); ``loss`` (probability) and
    ``delay`` [s] inject faults on every message both ways with ``seed``; ``virtual_time``: the controller's clock
    is virtual (``--speed max``), so it may wait for the link rather than drop telemetry; ``bodies`` the specimens
    on the plate in body-id order (reported to the host); ``security`` the zenoh link's TLS identity, or plain text
    off loopback explicitly allowed (zenoh only; ``protocols.zenoh.config``); ``replay_state`` the file that keeps
    the signatures' stamps across restarts (``sim_table.replay_store``; None: in memory only, the transports that
    sign).
    """

    key: bytes = field(repr=False)
    clock: Callable[[int], int]
    table: TableModel
    loss: float = 0.0
    delay: float = 0.0
    seed: int = 0
    virtual_time: bool = False
    bodies: tuple[BodyOnPlate, ...] = ()
    security: LinkSecurity = PLAIN
    replay_state: Path | None = None


class Endpoint(Protocol):
    """The controller end of one transport (module docstring)."""

    url: str
    """The URL it listens on, ports resolved (``mavlink://127.0.0.1:0`` → the port it got)."""
    stall_chunks: bool
    """Set by the owner to drop every setpoint chunk from then on (injected stalled stream)."""

    def start(self) -> None: ...
    def take(self, now: int) -> list[tuple[int, Action]]: ...
    def command_done(self, done: Done) -> None: ...
    def chunk_refused(self, refused: Refused) -> None: ...
    def send_status(self, snap: Snapshot) -> None: ...
    def add_accel(self, sensor_id: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> None: ...
    def flush_accel(self) -> None: ...
    def add_tilt(self, body_id: int, t_start_ns: int, spacing_ns: int, angles: np.ndarray) -> None: ...
    def flush_tilt(self) -> None: ...
    def send_overturn(self, event_id: int, body_id: int, direction: int, tilt: float, t_ns: int) -> None: ...
    def service(self, now: int, state: State) -> None: ...
    def close(self) -> None: ...
    def counters_dict(self) -> dict[str, Any]: ...


class Batch(NamedTuple):
    """Batch ``seq`` (counted per source from 0, modulo 2^32) of ``source`` (a sensor, a body): row k of ``samples``
    was taken at ``t_start_ns + k * spacing_ns`` [ns, controller time]."""

    source: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray


class Batcher:
    """Gathers evenly spaced samples per source into batches of ``size``. A source's first :meth:`add` sets its
    start time and spacing; every later one continues it (its own times are not looked at again)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._pending: dict[int, tuple[int, int, np.ndarray, int]] = {}  # source -> (t0, spacing, samples, seq)

    def add(self, source: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> list[Batch]:
        """Queue ``source``'s next ``samples`` (n, ...), the first at ``t_start_ns`` [ns] if it is the source's
        first; the batches now full."""
        t0, spacing, pending, seq = self._pending.get(source, (t_start_ns, spacing_ns, samples[:0], 0))
        pending = np.concatenate([pending, samples])
        batches = []
        while len(pending) >= self.size:
            batches.append(Batch(source, seq % 2**32, t0, spacing, pending[:self.size]))
            pending, seq, t0 = pending[self.size:], seq + 1, t0 + self.size * spacing
        self._pending[source] = (t0, spacing, pending, seq)
        return batches

    def flush(self) -> list[Batch]:
        """The samples still short of a full batch: one (shorter) batch for each source that has any."""
        batches = []
        for source, (t0, spacing, pending, seq) in list(self._pending.items()):
            if len(pending):
                batches.append(Batch(source, seq % 2**32, t0, spacing, pending))
                self._pending[source] = (t0 + len(pending) * spacing, spacing, pending[:0], seq + 1)
        return batches


class BatchedTelemetry:
    """The `Endpoint` methods that batch accelerometer and tilt samples (MAVLink, zenoh): the endpoint sets
    ``_accel`` and ``_tilt`` (a :class:`Batcher` each, of its transport's batch sizes) and sends each batch in
    :meth:`_send_accel` / :meth:`_send_tilt`."""

    _accel: Batcher
    _tilt: Batcher

    def add_accel(self, sensor_id: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> None:
        """Queue a sensor's next samples (n, 3), the first at ``t_start_ns``; full batches are sent at once."""
        for batch in self._accel.add(sensor_id, t_start_ns, spacing_ns, samples):
            self._send_accel(batch)

    def flush_accel(self) -> None:
        """Send the samples still short of a full batch."""
        for batch in self._accel.flush():
            self._send_accel(batch)

    def add_tilt(self, body_id: int, t_start_ns: int, spacing_ns: int, angles: np.ndarray) -> None:
        """Queue a body's next tilt angles (n,) [rad], the first at ``t_start_ns``; full batches are sent at once."""
        for batch in self._tilt.add(body_id, t_start_ns, spacing_ns, angles):
            self._send_tilt(batch)

    def flush_tilt(self) -> None:
        """Send the angles still short of a full batch."""
        for batch in self._tilt.flush():
            self._send_tilt(batch)

    def _send_accel(self, batch: Batch) -> None:
        raise NotImplementedError

    def _send_tilt(self, batch: Batch) -> None:
        raise NotImplementedError


@runtime_checkable
class LegFeedback(Protocol):
    """An endpoint whose drives report each leg's measured length (CANopen: at every SYNC) and watch its following
    error: the loop gives it the legs' true and commanded lengths of every tick."""

    def add_legs(self, t_start_ns: int, spacing_ns: int, lengths: np.ndarray, commanded: np.ndarray) -> None: ...


@runtime_checkable
class LimitReports(Protocol):
    """An endpoint that takes the host's limit levels (SET_LIMIT) and reports the controller's trips of them: the
    loop gives it each :class:`~analysis.table.controller_limits.ControllerTrip` as the table starts to act on
    it. An endpoint without it refuses SET_LIMIT (the host's detectors then act alone)."""

    def limit_tripped(self, trip: ControllerTrip) -> None: ...


@runtime_checkable
class HeldAnswers(Protocol):
    """An endpoint whose command answers carry no controller time (MAVLink's COMMAND_ACK): it holds the answers
    given during a batch and sends them when the loop says, after the batch's statuses, so that the host receives
    the status showing what a command did before its answer, and a status taken after it next."""

    def send_answers(self) -> bool: ...


@runtime_checkable
class Rests(Protocol):
    """An endpoint that can forget its hosts (MAVLink, zenoh): no owner, no peer, no command in progress or
    remembered, every counter zero; the signatures' replay guard kept. What ``sim_table.process.Emulator.rest``
    needs of it (CANopen's drives keep their own state machines: not offered there)."""

    def rest(self) -> None: ...


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
