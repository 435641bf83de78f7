"""The emulator process: ``python -m sim_table --listen URL [options]`` (or ``rig emulate``).

One loop owns the emulated table: it wakes at absolute deadlines (:data:`WAKE_PERIOD_NS`, on CANopen
:data:`CANOPEN_WAKE_PERIOD_NS`), runs every 1 ms controller tick due by then in one batch — host messages applied at
their arrival time, the reference through the actuators, the achieved motion into the accelerometers and the
MuJoCo specimens (tilt samples at :data:`TILT_RATE` [Hz]) — and sends what the batch produced (a status every
20 ms of controller time and at every state change, batches, answers, heartbeats). Controller time [ns] is
``speed × (host monotonic − start)``; ``--speed max`` is virtual time (at most :data:`VIRTUAL_BATCH` ticks a
batch, the clock holding at a stream's last buffered setpoint); the link watchdogs keep ``--watchdog`` of real time
at any speed. Specimens are placed afresh (upright, at rest, where ``--body`` puts them) at every START_STREAM: the
emulator is also the operator.

Fault injection: ``--loss PCT`` and ``--delay MS`` on every datagram both ways; ``--drive-fault-at S`` raises a
drive fault, ``--stall-at S`` drops every setpoint chunk and ``--leg-stall LEG@S`` seizes leg LEG's actuator (it
brakes to rest and stops following its command: on CANopen its drive's following-error supervision trips) from
S seconds (controller time) after the first START_STREAM; ``--door-open S:D`` sets the enclosure door input and
``--accel-noisy ID@S:D`` makes accelerometer ID noisy for D s from S s after it. At exit (SIGINT, SIGTERM) the
counters are written as one JSON object to stdout, or to ``--counters FILE``. SIGUSR1 brings the table back to its
power-up state (at home, idle, no owner, counters zero: :meth:`Emulator.rest`; MAVLink and zenoh) and writes the
counters up to then as one JSON line to stdout, what tests sharing one emulator do between two tests; only the
emulator's own user can send it.

Signing key (``--key-file``, else ``$SHAKETABLE_MAVLINK_KEY``): needed on the transports that sign, mavlink and
zenoh; not on canopen, which has no authentication (the bus is a private cable). On those two the signatures' last
stamps are kept across restarts in ``--replay-state FILE`` (default: beside the key file, ``sim_table.replay_store``).

The loop's steps, its wake periods and virtual time: docs/table-controller.md §The emulator's loop and §Virtual time.
"""

from __future__ import annotations

import bisect
import contextlib
import gc
import itertools
import json
import math
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from analysis.table.controller_limits import ControllerTrip
from analysis.table.model import TableModel
from protocols.signing_key import KEY_ENV, load_signing_key
from protocols.zenoh.config import PLAIN, LinkSecurity
from protocols.zenoh.tls import TlsOptions, load_tls
from sim_table.accelerometers import Accelerometers, PlateTrack, sheet_accelerometers
from sim_table.actuators import ActuatorSettings
from sim_table.controller import ControllerCore, Done, Fault, Refused, Snapshot, State
from sim_table.dynamics import make_actuators, specimen_loads
from sim_table.endpoint import (
    BodyOnPlate,
    EndpointOptions,
    HeldAnswers,
    LegFeedback,
    LimitReports,
    Rests,
    listen_scheme,
    open_endpoint,
)
from sim_table.options import argument_parser
from sim_table.replay_store import default_path
from sim_table.scene import Specimen, parse_body
from sim_table.specimens import SpecimenScene
from sim_table.tick_profile import TickProfile

WAKE_PERIOD_NS = 20_000_000
"""The loop's wake-up period [ns, real time] on MAVLink and zenoh: twenty ticks a wake at speed 1, one batch (the
per-call cost of the vectorised kinematics and of MuJoCo's rollout shared by twenty ticks: with two ticks a wake
the emulator spent about three times the CPU a tick). Host messages are still applied at their arrival time between
the ticks; what the batch produced (statuses, telemetry, answers) goes out at its end, at most this late — well
inside the host's lead (1 s) and link timeout (0.5 s)."""

CANOPEN_WAKE_PERIOD_NS = 10_000_000
"""The wake-up period [ns, real time] on CANopen: its drives answer each SYNC with the physics of that instant, so an
answer waits for the batch that computes it, at most this long (the master takes the answers as they come and
publishes 50 statuses a second). Ten ticks a batch: with two the emulator spent 0.41 ms of CPU a tick (0.33 with
four, 0.13 with twenty, idle, measured), and shared with the master in one interpreter (the tests) it left the SYNCs
no room."""

REST_WAKE_PERIOD_NS = 2_000_000
"""The wake-up period [ns, real time] of virtual time at rest (its ticks run at real time then, a command is taken
up within it)."""

PARENT_POLL_S = 0.2
"""How often ``--exit-with-parent`` looks whether the parent process is still there [s]."""

MAX_BATCH = 200
"""Most ticks run between two looks at the network (a long stall is caught up over several wakes)."""

VIRTUAL_BATCH = 80
"""Most ticks an iteration in virtual time (the batch's kinematics and MuJoCo steps in one call each): its statuses
(every 20 ticks) go out at its end, well within the 250 ms the host's setpoints may run ahead of the last status
(``drivers/chunked.py``), so the host keeps the buffer supplied while the next batch runs."""

VIRTUAL_BATCH_WALL_NS = 50_000_000
"""Wall time [ns] a virtual-time batch is sized to take: the next batch's ticks are cut to this over the last
batch's wall time per tick (at least one tick). On a host that other work keeps busy a batch of 80 ticks with seven
bodies in contact can take most of a second of wall time, and its statuses — sent at its end — then leave the
host's link timeout (0.5 s) without a status: measured 2026-11-28, a compensation benchmark case through the
emulator was stopped with "no status for 0.8 s" at a load average of 7–10."""

LIMIT_BATCH = 10
"""Most ticks a batch runs while the controller's own limit levels watch a stream (``sim_table.limit_levels``):
the levels are evaluated on the batch's samples once its physics ran, and a trip's stop begins at the next tick,
so the crossing-to-stop time in table time is at most this many ticks plus one (11 ms at 1 kHz), inside one
status period (:data:`STATUS_PERIOD_NS`)."""

HOLD_POLL_S = 0.0005
"""How long virtual time sleeps [s, real time] between looks at the network while it holds for setpoints."""

_AT_REST = frozenset({State.IDLE, State.ARMED, State.FAULTED, State.EMERGENCY_STOPPED})
"""States in which virtual time ticks at real time (nothing to hurry)."""

STATUS_PERIOD_NS = 20_000_000
"""Status period [ns, controller time] (50 Hz)."""

INJECTED = {"injected": True}
"""Metadata of the :class:`EmulatorConfig` fields that inject a fault (``Emulator._inject_faults`` acts on them):
a tick looks for injected faults only when one of them is set."""


VIRTUAL_WATCHDOG_SECONDS = 1.0
"""Stream and heartbeat watchdogs in virtual time [s, host time]: the table waits, still, for setpoints it has not
got, so host silence endangers nothing until the stream is over; a host busy logging a stream played several
times faster than real time may pause its sender longer than 100 ms, and a silent host is still stopped."""

TILT_RATE = 200.0
"""Sample rate of the bodies' tilt sensors [Hz] (the overturn detector's channel: each body's angle relative to the
plate, ``sim_table.specimens``): every ``round(controller_rate / TILT_RATE)``-th tick — every 5th at the default
1 kHz, 5 ms apart —, at the tick times whose controller time [ns] is a multiple of that spacing, dated as the
accelerometer samples are (the plate's time, one tick late). Each body's samples go to the endpoint's ``add_tilt``,
fallen bodies' too; without bodies nothing is sent."""

TIMING_WINDOW = 100_000
"""Batches kept for the tick-time percentiles in the counters."""

NOISY_ACCEL_SIGMA = 0.5
"""The noise σ a noisy accelerometer (``--accel-noisy``) adds to its own [m/s²], on every axis."""

SIGNING_SCHEMES = frozenset({"mavlink", "zenoh"})
"""Transports that authenticate motion commands and setpoints with the rig's signing key (CANopen has no
authentication: the bus is a private cable, and the emulator needs no key for it)."""


@dataclass(frozen=True)
class EmulatorConfig:
    """Everything the emulator runs with (see :func:`parse_args` for the command line).

    ``key``: the signing key, required on the transports that sign (:data:`SIGNING_SCHEMES`), unused on CANopen;
    ``leg_stall``: (leg 1..6, seconds after the first START_STREAM) when that leg's actuator seizes;
    ``replay_state``: the file that keeps the signatures' stamps across restarts (``sim_table.replay_store``; None:
    in memory only — the command line always gives one on the transports that sign).
    ``watchdog`` [s, controller time]: the host-heartbeat and setpoint watchdogs at 1x and faster (None: the
    table's ``link.watchdog_s``; virtual time uses :data:`VIRTUAL_WATCHDOG_SECONDS`); ``buffer`` [s]: the
    setpoint buffer's capacity (None: the table's ``link.buffer_s``).
    """

    listen: str
    key: bytes | None = field(default=None, repr=False)
    speed: float = 1.0
    specimens: tuple[Specimen, ...] = ()
    sensors: tuple[tuple[float, float, float], ...] | None = None
    """The accelerometers' places [m, plate frame], each with the plate's axes (``--accel``); None: where the
    table's calibration sheets put them, with their axes (``[sensors]``: :func:`sheet_accelerometers`)."""
    table: TableModel = field(default_factory=TableModel)
    actuators: ActuatorSettings = field(default_factory=ActuatorSettings)
    dynamics: str = "lag"
    accel_noise: float = 0.02
    loss: float = 0.0
    delay: float = 0.0
    drive_fault_at: float | None = field(default=None, metadata=INJECTED)
    stall_at: float | None = field(default=None, metadata=INJECTED)
    leg_stall: tuple[int, float] | None = field(default=None, metadata=INJECTED)
    door_open: tuple[float, float] | None = field(default=None, metadata=INJECTED)
    """The enclosure door open from S s after the first stream start for D s (controller time): (S, D)."""
    accel_noisy: tuple[int, float, float] | None = field(default=None, metadata=INJECTED)
    """Accelerometer ID noisy (σ :data:`NOISY_ACCEL_SIGMA` more) from S s after the first stream start for D s
    (controller time): (ID, S, D)."""
    seed: int = 0
    watchdog: float | None = None
    buffer: float | None = None
    security: LinkSecurity = PLAIN
    replay_state: Path | None = None

    def __post_init__(self) -> None:
        if not (self.speed > 0):  # math.inf: virtual time (--speed max)
            raise ValueError(f"speed must be > 0 or max, got {self.speed!r}")
        if self.watchdog is not None and not (math.isfinite(self.watchdog) and self.watchdog > 0):
            raise ValueError(f"watchdog must be > 0 s, got {self.watchdog!r}")
        if self.buffer is not None and not (math.isfinite(self.buffer) and 0 < self.buffer <= 120):
            raise ValueError(f"buffer must be in (0, 120] s, got {self.buffer!r}")
        for name in ("drive_fault_at", "stall_at"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0 s, got {value!r}")
        if self.leg_stall is not None:
            leg, at = self.leg_stall
            if not (isinstance(leg, int) and 1 <= leg <= 6 and math.isfinite(at) and at >= 0):
                raise ValueError(f"leg_stall must be (leg 1..6, >= 0 s), got {self.leg_stall!r}")
        if self.sensors is not None and self.table.sensors.sheets:
            raise ValueError("--accel places accelerometers the rig configuration's [sensors] sheets place too: "
                             "give one or the other")
        count = len(self.accelerometer_places()[0])
        if self.accel_noisy is not None and not 0 <= self.accel_noisy[0] < count:
            raise ValueError(f"--accel-noisy: no accelerometer {self.accel_noisy[0]} on the emulated plate (it has "
                             f"{count}: ids 0 to {count - 1})")
        scheme = listen_scheme(self.listen)
        if math.isinf(self.speed) and scheme == "canopen":
            raise ValueError("--speed max: CANopen has no virtual time (its master, the host, is the controller and "
                             "paces the SYNC in real time)")
        if scheme in SIGNING_SCHEMES and self.key is None:
            raise ValueError(f"--listen {self.listen}: {scheme} signs motion commands and setpoints and needs the "
                             f"rig's signing key: give --key-file FILE or set {KEY_ENV} (64 hexadecimal digits)")
        if scheme != "zenoh" and self.security != PLAIN:
            raise ValueError(f"--listen {self.listen}: --tls-ca/--tls-cert/--tls-key and --insecure-plain-tcp are "
                             "options of a zenoh link")


    def accelerometer_places(self) -> tuple[np.ndarray, np.ndarray]:
        """The accelerometers' places (m, 3) [m, plate frame] and mountings (m, 3, 3) (plate frame → their axes)."""
        if self.sensors is None:
            return sheet_accelerometers(self.table.sensors)
        return np.array(self.sensors, dtype=float), np.tile(np.eye(3), (len(self.sensors), 1, 1))


class Emulator:
    """The emulated table behind one endpoint (module docstring). :meth:`run` until ``stop`` is set."""

    def __init__(self, config: EmulatorConfig) -> None:
        self.config = config
        table = config.table
        self.tick_ns = round(1e9 / table.controller_rate)
        dt = self.tick_ns * 1e-9
        self.virtual = math.isinf(config.speed)
        """Virtual time (``--speed max``, module docstring)."""
        capacity = math.ceil((table.link.buffer_s if config.buffer is None else config.buffer) * table.controller_rate)
        self._capacity = capacity
        self.core = self._new_core()
        self.wake_period_ns = CANOPEN_WAKE_PERIOD_NS if listen_scheme(config.listen) == "canopen" else WAKE_PERIOD_NS
        """The real-time loop's wake-up period [ns] (module docstring)."""
        self.actuators = make_actuators(config.dynamics, table, dt, config.actuators, seed=config.seed,
                                        loads=specimen_loads(config.specimens))
        self.track = PlateTrack(dt)
        self.accelerometers = self._new_accelerometers()
        self.profile = TickProfile()
        """The tick thread's CPU time per stage (``sim_table.tick_profile``), in the counters' ``timing``."""
        self.scene = SpecimenScene(config.specimens, profile=self.profile) if config.specimens else None
        self.tilt_spacing_ns = max(1, round(table.controller_rate / TILT_RATE)) * self.tick_ns
        """Time between two samples of a tilt sensor [ns, controller time] (:data:`TILT_RATE`)."""
        self._start = time.monotonic_ns()
        self.endpoint = open_endpoint(config.listen, EndpointOptions(
            key=config.key or b"", clock=self.controller_time, table=table, loss=config.loss, delay=config.delay,
            seed=config.seed + 2, virtual_time=self.virtual, security=config.security,
            bodies=tuple(BodyOnPlate(s.body.b, s.body.h, s.depth, s.x, s.y) for s in config.specimens),
            replay_state=config.replay_state))
        self.url = self.endpoint.url
        self._answers = self.endpoint if isinstance(self.endpoint, HeldAnswers) else None  # checked once: slow
        self._legs = self.endpoint if isinstance(self.endpoint, LegFeedback) else None  # checked once: slow
        self._next_tick = self.tick_ns
        self._pending: deque[tuple[int, Any]] = deque()
        self._events = 0
        self._drive_fault_done = False
        self._leg_stalled = False
        self._injecting = any(getattr(config, option.name) is not None for option in fields(config)
                              if option.metadata.get("injected"))
        """Whether a fault is injected (:meth:`_inject_faults` looks at every tick; else it has nothing to do)."""
        self._batches: deque[tuple[int, int]] = deque(maxlen=TIMING_WINDOW)  # (ticks, busy ns)
        self._batches_lock = threading.Lock()  # counters() may be read from another thread (in-process emulator)
        self._ticks = 0
        self._busy_ns = 0
        self._cpu_ns = 0
        self._lag_max_ns = 0
        self._overturns: list[dict[str, float]] = []
        self._clock = 0  # virtual time: the last tick run [ns]
        self._rest_credit = 0  # virtual time at rest: real time not yet ticked [ns]
        self._held_status: tuple[int, int] | None = None  # virtual time: (clock, host ns) of the last hold status
        self._virtual_cap = VIRTUAL_BATCH  # virtual time: the next batch's most ticks (VIRTUAL_BATCH_WALL_NS)
        self._virtual_full = False  # virtual time: the last iteration ran as many ticks as its cap allowed
        self._last_legs = (self.actuators.lengths, self.actuators.pose)  # true leg lengths and pose, last tick
        self._last_centre = np.zeros(6)  # the true pose one tick late (where the specimens' plate is)
        self._last_following = np.zeros(6)  # each leg's commanded minus true length at the last tick [m]
        self.rest_requested = threading.Event()
        """Set (from a signal handler or another thread) to have the loop :meth:`rest` the table."""
        self._on_rest: Callable[[dict[str, Any]], None] | None = None

    def _new_core(self) -> ControllerCore:
        """The controller as at power-up: idle at home, no fault, every counter zero."""
        config, table = self.config, self.config.table
        if self.virtual:
            return ControllerCore(table, tick_ns=self.tick_ns, watchdog_ns=round(VIRTUAL_WATCHDOG_SECONDS * 1e9),
                                  link_clock=time.monotonic_ns, buffer_capacity=self._capacity)
        watchdog = table.link.watchdog_s if config.watchdog is None else config.watchdog
        csp = listen_scheme(config.listen) == "canopen"  # the master plays the drive: its drives hold on a gap
        return ControllerCore(table, tick_ns=self.tick_ns, watchdog_ns=round(watchdog * config.speed * 1e9),
                              buffer_capacity=self._capacity, underrun_stops=not csp)

    def _new_accelerometers(self) -> Accelerometers:
        """The accelerometers as at power-up: nominal noise, their noise drawn from the seed's start."""
        config = self.config
        places, mountings = config.accelerometer_places()
        return Accelerometers(places, self.tick_ns * 1e-9, mountings=mountings, noise=config.accel_noise,
                              seed=config.seed + 1)

    def rest(self) -> dict[str, Any]:
        """Bring the table back to its state at power-up, between two tests that share one emulator (SIGUSR1,
        :func:`main`): returns the counters up to now, then the controller is idle at home with no fault, the legs
        at home and at rest, the specimens re-seated upright, the accelerometers at their nominal noise drawn from
        the seed's start (a session played after a rest measures what it would on a fresh emulator), nobody owns
        the table, every counter (the link's, the timing, the overturns) is zero and no fault injection has
        happened yet. Controller time runs on (it never
        goes back: the hosts' clocks stay valid) and the signatures' replay guard is kept (a message signed before
        the reset is still refused as a replay after it). Runs on the loop's thread, between two iterations.
        ValueError on an endpoint that cannot forget its hosts (CANopen: :class:`~sim_table.endpoint.Rests`)."""
        if not isinstance(self.endpoint, Rests):
            raise ValueError(f"{listen_scheme(self.config.listen)}: the emulator cannot be brought back to rest on "
                             "this transport (only mavlink and zenoh)")
        counters = self.counters()
        config, table = self.config, self.config.table
        self.core = self._new_core()
        self.actuators = make_actuators(config.dynamics, table, self.tick_ns * 1e-9, config.actuators,
                                        seed=config.seed, loads=specimen_loads(config.specimens))
        self.track = PlateTrack(self.tick_ns * 1e-9)
        self.accelerometers = self._new_accelerometers()  # a noisy one (--accel-noisy) quiet again, the noise anew
        self._last_legs = (self.actuators.lengths, self.actuators.pose)
        self._last_centre = np.zeros(6)
        self._last_following = np.zeros(6)
        if self.scene is not None:
            self.scene.place(self._last_centre)
        self.endpoint.rest()
        self._pending.clear()
        self._drive_fault_done = self._leg_stalled = False
        with self._batches_lock:
            self._batches.clear()
        self._ticks = self._busy_ns = self._cpu_ns = self._lag_max_ns = 0
        self.profile.clear()
        self._overturns = []
        self._held_status = None
        return counters

    def controller_time(self, host_ns: int) -> int:
        """Controller time [ns] at host monotonic time ``host_ns`` (virtual time: the last tick's, whatever
        ``host_ns``)."""
        if self.virtual:
            return self._clock
        return int((host_ns - self._start) * self.config.speed)

    def run(self, stop: threading.Event, on_rest: Callable[[dict[str, Any]], None] | None = None) -> None:
        """Start the clock and the endpoint, tick in real time (× speed) or virtual time until ``stop`` is set;
        then send the last accelerometer and tilt samples. Between two iterations, when :attr:`rest_requested` is
        set: :meth:`rest`, its counters to ``on_rest``."""
        self._start = deadline = time.monotonic_ns()
        self.endpoint.start()
        self._on_rest = on_rest
        if self.virtual:
            self._run_virtual(stop)
            self._flush()
            return
        while not stop.is_set():
            self._rest_if_requested()
            deadline += self.wake_period_ns
            now = time.monotonic_ns()
            if deadline > now:
                time.sleep((deadline - now) * 1e-9)
            else:
                deadline = now  # late: run what is due now, do not burst to catch up missed wakes
            self.step(time.monotonic_ns())
        self._flush()

    def _rest_if_requested(self) -> None:
        if self.rest_requested.is_set():
            self.rest_requested.clear()
            counters = self.rest()
            if self._on_rest is not None:
                self._on_rest(counters)

    def _flush(self) -> None:
        """Send the samples the endpoint holds short of a full batch."""
        self.endpoint.flush_accel()
        self.endpoint.flush_tilt()

    def step(self, now: int) -> None:
        """Run every tick due at host time ``now`` [ns] (at most :data:`MAX_BATCH`), then send."""
        cpu = time.thread_time_ns()
        self.profile.start()
        self._pending.extend(self.endpoint.take(now))
        self.profile.lap("transport")
        due = (self.controller_time(now) - self._next_tick) // self.tick_ns + 1
        count = int(min(max(due, 0), MAX_BATCH))
        if count:
            times = self._next_tick + self.tick_ns * np.arange(count, dtype=np.int64)
            self._next_tick = int(times[-1]) + self.tick_ns
            done = 0
            while done < count:  # in batches of at most LIMIT_BATCH ticks while the controller's levels watch
                ticks = self._batch_ticks(count - done)
                self._batch(times[done:done + ticks])
                done += ticks
            busy = time.monotonic_ns() - now
            with self._batches_lock:
                self._batches.append((count, busy))
            self._ticks += count
            self._busy_ns += busy
            self._cpu_ns += time.thread_time_ns() - cpu
            oldest = (self.controller_time(now) - int(times[0])) / self.config.speed  # how late its first tick ran
            self._lag_max_ns = max(self._lag_max_ns, round(oldest))
        self.endpoint.service(time.monotonic_ns(), self.core.state)
        if count:
            self.profile.lap("transport")
            self.profile.commit()

    def _run_virtual(self, stop: threading.Event) -> None:
        """Virtual time (module docstring): tick while there is something to do, hold for setpoints, rest at real
        time."""
        last = time.monotonic_ns()
        while not stop.is_set():
            self._rest_if_requested()
            now = time.monotonic_ns()
            self._rest_credit += now - last
            last = now
            self.step_virtual(now)
            if self._virtual_full:
                time.sleep(0)  # let the endpoint's threads take the host's messages
            elif self.core.state in _AT_REST:
                time.sleep(REST_WAKE_PERIOD_NS * 1e-9)  # at rest in virtual time: ticks at real time
            else:
                time.sleep(HOLD_POLL_S)

    def step_virtual(self, now: int) -> int:
        """One iteration of virtual time at host time ``now`` [ns]: the ticks it may run (module docstring), or
        the watchdogs, answers and a status while it holds; then send. How many ticks ran."""
        cpu = time.thread_time_ns()
        profile = self.profile
        profile.start()
        core = self.core
        taken = self.endpoint.take(now)
        profile.lap("transport")
        for _, action in taken:  # stamped with the clock: due before the next tick
            action(core)
        moving = core.state not in _AT_REST
        cap = 0
        if moving:
            self._rest_credit = 0
            cap = count = self._batch_ticks(self._virtual_cap)
            until = core.buffered_until
            if until is not None:
                count = max(0, min(count, (until - self._next_tick) // self.tick_ns + 1))
        else:
            count = min(self._rest_credit // self.tick_ns, MAX_BATCH)
            self._rest_credit -= count * self.tick_ns
        self._virtual_full = moving and count == cap
        if count:
            times = self._next_tick + self.tick_ns * np.arange(count, dtype=np.int64)
            self._next_tick = int(times[-1]) + self.tick_ns
            started = time.monotonic_ns()
            self._batch(times)
            if moving:  # size the next batch to VIRTUAL_BATCH_WALL_NS at this one's wall time per tick
                per_tick = max(1, time.monotonic_ns() - started) / count
                self._virtual_cap = max(1, min(VIRTUAL_BATCH, int(VIRTUAL_BATCH_WALL_NS / per_tick)))
            self._clock = int(times[-1])
            busy = time.monotonic_ns() - now
            with self._batches_lock:
                self._batches.append((count, busy))
            self._ticks += count
            self._busy_ns += busy
            self._cpu_ns += time.thread_time_ns() - cpu
        else:
            self._hold(now)
        self.endpoint.service(time.monotonic_ns(), core.state)
        if count:
            profile.lap("transport")
            profile.commit()
        return int(count)

    def _hold(self, now: int) -> None:
        """Virtual time holds for setpoints: run the watchdogs, answer, and report the state and where the clock
        holds (at once, then every :data:`STATUS_PERIOD_NS` of host time ``now`` [ns] — a lost status must not
        leave the host waiting —, and at every change)."""
        core, endpoint = self.core, self.endpoint
        core.watch()
        changed = False
        for event in core.take_events():
            if isinstance(event, Done):
                endpoint.command_done(event)
            elif isinstance(event, Refused):
                endpoint.chunk_refused(event)
            elif isinstance(event, ControllerTrip):
                self._report_trip(event)
            else:
                changed = True
                if event.new is State.STREAMING and self.scene is not None:
                    self.scene.place(self._last_centre)
        held = self._held_status
        if changed or held is None or held[0] != self._clock or now - held[1] >= STATUS_PERIOD_NS:
            self._held_status = (self._clock, now)
            endpoint.send_status(self._held_snapshot())
        if self._answers is not None and self._answers.send_answers():
            endpoint.send_status(self._held_snapshot())

    def _held_snapshot(self) -> Snapshot:
        """The status while virtual time holds: the pose and the legs' following errors of the last tick."""
        snap = self.core.snapshot(self._clock, self.actuators.measure(*self._last_legs))
        return replace(snap, following_error=self._last_following)

    def _batch(self, times: np.ndarray) -> None:
        core, endpoint, profile = self.core, self.endpoint, self.profile
        n = len(times)
        reference = np.empty((n, 6))
        braked = np.empty(n, dtype=bool)
        statuses: list[tuple[int, Snapshot]] = []  # (tick index, status without the pose)
        placements: list[int] = []
        streaming_statuses: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # for the status levels
        ticks = times.tolist()
        status_ticks = np.flatnonzero(times % STATUS_PERIOD_NS == 0).tolist()  # a status after each
        i = 0
        while i < n:
            t = ticks[i]
            while self._pending and self._pending[0][0] <= t:
                self._pending.popleft()[1](core)
            if not self._injecting:  # plain stream ticks up to the next status or host message in one call
                k = bisect.bisect_left(status_ticks, i)
                stop = status_ticks[k] + 1 if k < len(status_ticks) else n
                if self._pending:
                    stop = min(stop, bisect.bisect_left(ticks, self._pending[0][0], lo=i))
                played = core.play_buffered(ticks, i, stop)
                if played:
                    reference[i:i + len(played)] = played
                    braked[i:i + len(played)] = False
                    i += len(played)
                    if ticks[i - 1] % STATUS_PERIOD_NS == 0:
                        statuses.append((i - 1, core.snapshot(ticks[i - 1], np.zeros(6))))
                    continue
            else:
                self._inject_faults(t)
            reference[i], braked[i] = core.tick(t)
            changed = False
            for event in core.take_events():
                if isinstance(event, Done):
                    endpoint.command_done(event)
                elif isinstance(event, Refused):
                    endpoint.chunk_refused(event)
                elif isinstance(event, ControllerTrip):
                    self._report_trip(event)
                else:
                    changed = True
                    if event.new is State.STREAMING:
                        placements.append(i)
            if changed or t % STATUS_PERIOD_NS == 0:
                statuses.append((i, core.snapshot(t, np.zeros(6))))
            i += 1
        profile.lap("controller")
        step = self.actuators.step(reference, braked)
        if step.setpoint_limited:
            core.raise_fault(Fault.SETPOINT_LIMIT, int(times[-1]))
        if step.stroke_limited:
            core.raise_fault(Fault.STROKE, int(times[-1]))
        core.observe(step.poses[-1])
        profile.lap("servo")
        if self._legs is not None:
            self._legs.add_legs(int(times[0]), self.tick_ns, step.lengths, step.commanded)
        if statuses:  # the batch's measured poses in one forward-kinematics call
            rows = [i for i, _ in statuses]
            measured = self.actuators.measure(step.lengths[rows], step.poses[rows])
            following = step.commanded[rows] - step.lengths[rows]
            for (_, snap), pose, error in zip(statuses, measured, following, strict=True):
                endpoint.send_status(replace(snap, pose=pose, following_error=error))
            streaming = [k for k, (_, snap) in enumerate(statuses) if snap.state is State.STREAMING]
            if streaming:  # the status levels on what each status of the stream reports
                streaming_statuses = (np.array([statuses[k][1].t_ns for k in streaming], dtype=np.int64),
                                      measured[streaming], following[streaming])
        self._last_legs = step.lengths[-1], step.poses[-1]
        self._last_following = step.commanded[-1] - step.lengths[-1]
        if self._answers is not None and self._answers.send_answers():  # then a status taken after the answers
            pose = self.actuators.measure(step.lengths[-1], step.poses[-1])
            endpoint.send_status(replace(core.snapshot(int(times[-1]), pose), following_error=self._last_following))
        profile.lap("transport")
        centre, rates, window = self.track.advance(step.poses)
        self._last_centre = centre[-1]
        force = self.accelerometers.measure(window)
        profile.lap("plate")
        for sensor in range(force.shape[1]):
            endpoint.add_accel(sensor, int(times[0]) - self.tick_ns, self.tick_ns, force[:, sensor])
        profile.lap("transport")
        if core.state is State.STREAMING:  # the downloaded levels on every tick's samples; the stop at the next tick
            trip = core.limit_levels.batch(times - self.tick_ns, force, *(streaming_statuses or ()))
            if trip is not None:
                core.limit_trip(trip, int(times[-1]) + self.tick_ns)
        if self.scene is not None:
            self._specimens(times - self.tick_ns, centre, rates, placements)

    def _report_trip(self, trip: ControllerTrip) -> None:
        """A trip of the controller's own levels to the host, on an endpoint that reports them."""
        if isinstance(self.endpoint, LimitReports):
            self.endpoint.limit_tripped(trip)

    def _batch_ticks(self, count: int) -> int:
        """How many of ``count`` due ticks the next batch runs: at most :data:`LIMIT_BATCH` while the controller's
        own limit levels watch a stream (its stop begins at the first tick after the batch that found the
        crossing)."""
        if self.core.limit_levels.levels:  # downloaded for the next stream, cleared at its end
            return min(count, LIMIT_BATCH)
        return count

    def _specimens(self, times: np.ndarray, poses: np.ndarray, rates: np.ndarray, placements: list[int]) -> None:
        """The specimens through the batch's ticks (``times`` [ns], the plate's ``poses`` and ``rates``), stepped in
        C between the ticks where they are placed afresh (``placements``); their overturns and tilt samples sent."""
        assert self.scene is not None
        seconds = times * 1e-9
        sampled: list[np.ndarray] = []  # the tilt sensors' samples (m, bodies), at the ticks on their grid
        first_sample: int | None = None  # controller time of the first [ns]
        for start, end in itertools.pairwise(sorted({0, *placements, len(times)})):
            if start in placements:
                self.scene.place(poses[start])
            part = np.arange(start, end)[seconds[start:end] > self.scene.time]
            if len(part) == 0:
                continue
            overturns = self.scene.advance_many(seconds[part], poses[part], rates[part])
            on_grid = times[part] % self.tilt_spacing_ns == 0
            if on_grid.any():
                first_sample = int(times[part][on_grid][0]) if first_sample is None else first_sample
                sampled.append(self.scene.sample_angles[on_grid])
            self.profile.lap("specimens")
            for overturn in overturns:
                i = part[min(int(np.searchsorted(seconds[part], overturn.t)), len(part) - 1)]  # its tick
                self._events += 1
                t_ns = round(overturn.t * 1e9)
                tilt = float(poses[i][4])
                self.endpoint.send_overturn(self._events, overturn.body_id, overturn.direction, tilt, t_ns)
                self._overturns.append({"event_id": self._events, "body_id": overturn.body_id,
                                        "direction": overturn.direction, "t": t_ns * 1e-9, "tilt": tilt})
            self.profile.lap("transport")
        if first_sample is not None:
            angles = np.concatenate(sampled)
            for body in range(angles.shape[1]):
                self.endpoint.add_tilt(body, first_sample, self.tilt_spacing_ns, angles[:, body])

    def _inject_faults(self, t: int) -> None:
        start = self.core.first_stream_ns
        if start is None:
            return
        cfg = self.config
        if cfg.drive_fault_at is not None and not self._drive_fault_done and t >= start + cfg.drive_fault_at * 1e9:
            self._drive_fault_done = True
            self.core.raise_fault(Fault.DRIVE, t)
        if cfg.stall_at is not None and t >= start + cfg.stall_at * 1e9:
            self.endpoint.stall_chunks = True
        if cfg.door_open is not None:
            opens = start + cfg.door_open[0] * 1e9
            self.core.inputs = int(opens <= t < opens + cfg.door_open[1] * 1e9)
        if cfg.accel_noisy is not None:
            sensor, opens_s, lasts_s = cfg.accel_noisy
            opens = start + opens_s * 1e9
            noisy = opens <= t < opens + lasts_s * 1e9
            self.accelerometers.sigma[sensor] = self.accelerometers.noise + NOISY_ACCEL_SIGMA * noisy
        if cfg.leg_stall is not None and not self._leg_stalled and t >= start + cfg.leg_stall[1] * 1e9:
            self._leg_stalled = True
            self.actuators.stalled[cfg.leg_stall[0] - 1] = True

    def counters(self) -> dict[str, Any]:
        """Everything counted, as plain JSON types."""
        with self._batches_lock:
            batches = np.array(self._batches, dtype=np.float64).reshape(-1, 2)
        if not len(batches):
            batches = np.zeros((1, 2))
        sizes, batch = batches[:, 0], batches[:, 1]
        per_tick = np.divide(batch, sizes, out=np.zeros_like(batch), where=sizes > 0)
        simulated = self._ticks * self.tick_ns
        timing = {
            "ticks": self._ticks,
            "tick_budget_us": self.tick_ns / self.config.speed * 1e-3,
            "tick_time_mean_us": self._busy_ns / max(self._ticks, 1) * 1e-3,
            "tick_cpu_mean_us": self._cpu_ns / max(self._ticks, 1) * 1e-3,
            "tick_time_p99_us": float(np.percentile(per_tick, 99)) * 1e-3,
            "batch_time_p99_us": float(np.percentile(batch, 99)) * 1e-3,
            "batch_time_max_us": float(batch.max()) * 1e-3,
            "batch_size_mean": float(sizes.mean()),
            "batch_size_max": int(sizes.max()),
            "real_time_factor": simulated / self._busy_ns if self._busy_ns else None,
            "lag_max_ms": self._lag_max_ns * 1e-6,
            "controller_time_s": self.controller_time(time.monotonic_ns()) * 1e-9,
            "profile_cpu_us_per_tick": self.profile.per_tick_us(self._ticks),
        }
        return {"url": self.url, "speed": "max" if self.virtual else self.config.speed, "state": self.core.state.value,
                "faults": [f.name for f in Fault if self.core.faults & f], **self.core.counters.as_dict(),
                "link": self.endpoint.counters_dict(), "timing": timing, "overturns": list(self._overturns)}

    def close(self) -> None:
        self.endpoint.close()


# ----- command line -------------------------------------------------------------------------------------


def parse_args(argv: list[str]) -> tuple[EmulatorConfig, Path | None, bool]:
    """The configuration, ``--counters`` path and ``--exit-with-parent`` of a command line (argparse errors
    exit 2)."""
    p = argument_parser()
    args = p.parse_args(argv)
    try:
        scheme = listen_scheme(args.listen)
        signs = scheme in SIGNING_SCHEMES
        key = load_signing_key(args.key_file) if signs and (args.key_file or os.environ.get(KEY_ENV)) else None
        replay_state = args.replay_state
        if key is not None and replay_state is None:
            if args.key_file is None:
                raise ValueError(f"--replay-state FILE is needed with the key from ${KEY_ENV}: the controller keeps "
                                 "the signatures' last stamps there across restarts (docs/table-controller.md)")
            replay_state = default_path(args.key_file, scheme)
        table = TableModel.from_toml(args.rig_config) if args.rig_config else TableModel()
        tls = load_tls(args.tls_ca, args.tls_cert, args.tls_key)
        if tls is None and scheme == "zenoh" and table.network.given:  # the rig configuration's [network]
            network = table.network
            tls = load_tls(network.ca, network.cert, network.key, names=TlsOptions(*network.where))
        config = EmulatorConfig(
            listen=args.listen, key=key, speed=args.speed,
            specimens=tuple(parse_body(b) for b in args.body), sensors=tuple(args.accel) if args.accel else None,
            table=table,
            actuators=ActuatorSettings() if args.leg_noise is None else ActuatorSettings(noise=args.leg_noise),
            dynamics=args.dynamics, accel_noise=args.accel_noise,
            loss=args.loss / 100.0, delay=args.delay * 1e-3, drive_fault_at=args.drive_fault_at,
            stall_at=args.stall_at, leg_stall=args.leg_stall, door_open=args.door_open,
            accel_noisy=args.accel_noisy, seed=args.seed,
            watchdog=args.watchdog,
            buffer=args.buffer, security=LinkSecurity(tls, args.insecure_plain_tcp),
            replay_state=replay_state if signs else None)
    except ValueError as exc:
        p.error(str(exc))
    return config, args.counters, args.exit_with_parent


def watch_parent(stop: threading.Event) -> None:
    """Set ``stop`` once the process that started this one has exited (this one re-parented), checked every
    :data:`PARENT_POLL_S`: an emulator started by ``rig`` ends with it, even after ``kill -9`` of ``rig``."""
    parent = os.getppid()

    def watch() -> None:
        while not stop.wait(PARENT_POLL_S):
            if os.getppid() != parent:
                stop.set()
                with contextlib.suppress(OSError):  # its pipes may have gone with it
                    print(f"sim_table: the parent process {parent} exited: stopping", file=sys.stderr, flush=True)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    """Run the emulator in the foreground until SIGINT or SIGTERM; write the counters; exit 0."""
    config, counters_path, with_parent = parse_args(sys.argv[1:] if argv is None else argv)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    if with_parent:
        watch_parent(stop)
    try:
        emulator = Emulator(config)
    except OSError as exc:
        print(f"sim_table: cannot listen on {config.listen}: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # bodies that overlap or do not fit the scene
        print(f"sim_table: {exc}", file=sys.stderr)
        return 2
    if isinstance(emulator.endpoint, Rests):  # before "listening": whoever reads that may send it at once
        signal.signal(signal.SIGUSR1, lambda *_: emulator.rest_requested.set())
    gc.collect()
    gc.freeze()  # the set-up out of reach of the collector: its full passes stay short while serving (drivers/heap)
    speed = "max" if emulator.virtual else f"{config.speed:g}"
    if config.security.insecure:
        print(f"sim_table: WARNING: --insecure-plain-tcp: the link at {emulator.url} may be plain text off loopback "
              "(nothing encrypted)", file=sys.stderr, flush=True)
    print(f"sim_table: listening on {emulator.url} (speed {speed}, {len(config.specimens)} bodies, "
          f"{len(emulator.accelerometers.places)} accelerometers)", file=sys.stderr, flush=True)
    try:
        emulator.run(stop, on_rest=lambda counters: print(json.dumps(counters), flush=True))
    finally:
        emulator.close()
    text = json.dumps(emulator.counters())
    if counters_path is not None:
        counters_path.write_text(text + "\n")
    else:
        with contextlib.suppress(OSError):  # a parent gone with its pipe (--exit-with-parent)
            print(text, flush=True)
    return 0
