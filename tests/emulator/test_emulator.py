"""The emulator's parts without sockets: the controller core (states, buffer, underruns, watchdogs), the actuator
model and the virtual accelerometers (``docs/table-controller.md``)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from analysis.body import G
from analysis.table.model import TableModel
from analysis.table.moves import IN_POSITION, SETTLE_TIME_NS
from protocols.mavlink import TILT_PER_BATCH
from protocols.signing_key import KEY_ENV, write_signing_key
from rig.drive.tilt import ramp_duration
from sim_table.accelerometers import Accelerometers, PlateTrack
from sim_table.actuators import Actuators, ActuatorSettings
from sim_table.controller import Command, ControllerCore, Done, Fault, Result, State, StateChange
from sim_table.endpoint import Batcher
from sim_table.process import (
    TILT_RATE,
    VIRTUAL_BATCH,
    VIRTUAL_BATCH_WALL_NS,
    Emulator,
    EmulatorConfig,
    parse_args,
    parse_body,
)

MS = 1_000_000
TABLE = TableModel()
SURGE_DECELERATION = TABLE.limits.surge.acceleration  # m/s², Table IV


def armed(pose: np.ndarray | None = None, **options: int) -> ControllerCore:
    core = ControllerCore(TABLE, pose=pose, **options)
    assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
    return core


def streaming(first_seq: int = 0, **options: int) -> ControllerCore:
    core = armed(**options)
    assert core.command(Command.START_STREAM, (float(first_seq),), True, 0) is Result.ACCEPTED
    return core


def run(core: ControllerCore, start_ms: int, stop_ms: int, *, heartbeat: bool = True) -> np.ndarray:
    """Ticks start..stop (ms, inclusive) with a heartbeat before each, ideal actuators (the achieved pose is the
    reference); the references (n, 6)."""
    out = []
    for ms in range(start_ms, stop_ms + 1):
        if heartbeat:
            core.heartbeat(ms * MS)
        reference, braked = core.tick(ms * MS)
        if not braked:
            core.observe(reference)
        out.append(reference.copy())
    return np.array(out)


def chunk(core: ControllerCore, seq: int, t0_ms: float, values: np.ndarray, *, end: bool = False,
          arrival_ms: float = 0.0, signed: bool = True) -> bool:
    """A chunk of surge values (n,) [m] at 1 ms spacing from t0_ms."""
    samples = np.zeros((len(values), 6))
    samples[:, 0] = values
    return core.chunk(seq, round(t0_ms * MS), MS, samples, end, signed, round(arrival_ms * MS))


def states(core: ControllerCore) -> list[State]:
    """The states entered since the last call."""
    return [e.new for e in core.take_events() if isinstance(e, StateChange)]


# ----- commands and states ----------------------------------------------------------------------------------


def test_motion_commands_and_chunks_need_a_signature_stopping_does_not() -> None:
    core = ControllerCore(TABLE)
    for command in (Command.ARM, Command.HOME, Command.SET_TILT, Command.START_STREAM):
        assert core.command(command, (0.0, 0.0), False, 0) is Result.DENIED
    assert not chunk(core, 0, 10, np.zeros(8), signed=False)
    assert core.counters.refused_commands == 5 and core.state is State.IDLE
    assert core.faults == Fault.UNSIGNED_COMMAND
    for command in (Command.STOP, Command.DISARM, Command.EMERGENCY_STOP):
        assert core.command(command, (), False, 0) is Result.ACCEPTED
    assert core.state is State.EMERGENCY_STOPPED and core.counters.refused_commands == 5
    assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
    assert core.state is State.ARMED and core.faults == Fault(0)  # ARM clears the latched faults


def test_commands_are_refused_in_states_that_do_not_take_them_or_with_bad_parameters() -> None:
    core = ControllerCore(TABLE)
    assert core.command(Command.HOME, (), True, 0) is Result.REJECTED  # idle
    core.command(Command.ARM, (), True, 0)
    assert core.command(Command.SET_TILT, (math.radians(11), 0.0), True, 0) is Result.FAILED  # beyond 10°
    assert core.command(Command.SET_TILT, (0.01, 2.0), True, 0) is Result.FAILED  # no such axis
    assert core.command(Command.START_STREAM, (0.5,), True, 0) is Result.FAILED
    assert core.command(Command.START_STREAM, (2.0**24,), True, 0) is Result.FAILED
    assert core.command(Command.START_STREAM, (7.0,), True, 0) is Result.ACCEPTED
    assert core.command(Command.DISARM, (), True, 0) is Result.REJECTED  # only at rest
    assert core.command(Command.ARM, (), True, 0) is Result.REJECTED
    assert core.counters.commands_rejected == 7 and core.counters.commands_accepted == 2


def test_set_tilt_ramps_as_the_drive_preparation_does_then_holds() -> None:
    beta = math.radians(5)
    core = armed()
    assert core.command(Command.SET_TILT, (beta, 0.0), True, 0) is Result.IN_PROGRESS
    expected = ramp_duration(beta, TABLE.limits.tilt, 1000.0)  # rig.drive.tilt, whole ms
    refs = run(core, 1, round(expected * 1000) + 5)
    events = core.take_events()
    done = [e for e in events if isinstance(e, Done)]
    assert done == [Done(done[0].t_ns, Command.SET_TILT, Result.ACCEPTED)]
    assert abs(done[0].t_ns * 1e-9 - expected) <= 1e-3
    assert [e.new for e in events if isinstance(e, StateChange)] == [State.ARMED, State.TILTING, State.ARMED]
    np.testing.assert_allclose(refs[-1], [0, 0, 0, 0, beta, 0], atol=1e-15)
    rate = np.diff(refs[:, 4]) * 1000
    assert rate.max() <= TABLE.limits.tilt.rate * (1 + 1e-6)


def test_stop_decelerates_then_goes_home_and_arms() -> None:
    core = streaming()
    ramp = 0.2e-3 * np.arange(1, 401)  # surge at 0.2 m/s
    for k in range(50):
        chunk(core, k, 1 + 8 * k, ramp[8 * k:8 * k + 8])
    run(core, 1, 100)
    states(core)
    assert core.command(Command.STOP, (), False, 100 * MS) is Result.ACCEPTED
    refs = run(core, 101, 1500)
    v = np.diff(refs[:, 0]) * 1000
    assert v[0] <= 0.2 and np.all(np.diff(v[:30]) >= -SURGE_DECELERATION * 1e-3 * (1 + 1e-9))
    assert states(core) == [State.STOPPING, State.ARMED]
    np.testing.assert_allclose(refs[-1], np.zeros(6), atol=1e-15)
    assert core.counters.stops == 1 and core.faults == Fault(0)
    assert core.snapshot(1500 * MS, refs[-1]).buffer_depth == 0


def test_a_move_ends_when_the_plate_is_in_position_and_a_plate_that_never_arrives_faults() -> None:
    """The reference of a 5° tilt arrives at T; a plate that only then starts to follow (first-order lag, τ = 5 ms)
    keeps the state ``tilting`` until it is within IN_POSITION of the target, τ·ln(β/IN_POSITION) ≈ 42 ms later;
    a plate held 1 mrad short faults (DRIVE, following error) SETTLE_TIME_NS after T and the table stops."""
    beta = math.radians(5)
    arrival = ramp_duration(beta, TABLE.limits.tilt, 1000.0)  # [s]
    end_ms = math.ceil(arrival * 1000)
    core = armed()
    assert core.command(Command.SET_TILT, (beta, 0.0), True, 0) is Result.IN_PROGRESS
    achieved, armed_at = np.zeros(6), None
    for ms in range(1, end_ms + 200):
        core.heartbeat(ms * MS)
        reference, _ = core.tick(ms * MS)
        if ms > end_ms:
            achieved = reference + (achieved - reference) * math.exp(-1e-3 / 0.005)
        core.observe(achieved)
        if armed_at is None and core.state is State.ARMED:
            armed_at, error = ms, np.abs(achieved - [0, 0, 0, 0, beta, 0]).max()
    # in position at T + ceil(42 ms); the tick after that observation arms
    assert armed_at == end_ms + math.ceil(5 * math.log(beta / IN_POSITION)) + 1 and error <= IN_POSITION

    core = armed()
    core.command(Command.SET_TILT, (beta, 0.0), True, 0)
    short = np.array([0, 0, 0, 0, beta - 1e-3, 0])
    for ms in range(1, end_ms + SETTLE_TIME_NS // MS + 2):
        core.heartbeat(ms * MS)
        core.tick(ms * MS)
        core.observe(short)
        if core.state is not State.TILTING:
            break
    assert abs(ms * 1e-3 - (arrival + SETTLE_TIME_NS * 1e-9)) <= 1e-3  # the tick past the settle time
    assert core.state is State.STOPPING and core.faults & Fault.DRIVE


# ----- the setpoint buffer ----------------------------------------------------------------------------------


def test_samples_are_interpolated_linearly_at_the_tick() -> None:
    core = streaming()
    t0 = 10.4  # ms: samples between the ticks
    values = 1e-5 * np.arange(16) ** 2  # at most 0.29 m/s: within the legs' speed
    chunk(core, 0, t0, values[:8])
    chunk(core, 1, t0 + 8, values[8:], end=True)
    refs = run(core, 11, 25)
    ticks = np.arange(11, 26)
    np.testing.assert_allclose(refs[:, 0], np.interp(ticks, t0 + np.arange(16), values), atol=1e-15)
    assert core.state is State.STREAMING  # the last sample is due at 25.4 ms
    run(core, 26, 26)
    assert core.state is State.ARMED and core.counters.streams_completed == 1
    assert core.counters.underruns == 0
    held = run(core, 27, 30)
    np.testing.assert_allclose(held[:, 0], values[-1])  # holds the last pose


def test_a_gap_filled_in_time_by_the_hosts_second_copy_is_no_fault() -> None:
    """Chunk 1's first copy lost, its second arriving after chunk 2 (the host sends each chunk again after the
    next): a gap while it is away, then reordered and played as sent — neither missing nor CHUNK_GAP."""
    core = streaming()
    chunk(core, 0, 1, 1e-4 * np.arange(8))
    chunk(core, 2, 17, 1e-4 * np.arange(16, 24))
    run(core, 1, 6)
    chunk(core, 1, 9, 1e-4 * np.arange(8, 16), arrival_ms=6)
    refs = run(core, 7, 24)
    np.testing.assert_allclose(refs[:, 0], 1e-4 * np.arange(6, 24), atol=1e-15)  # the chunk's own samples
    assert core.counters.chunks_reordered == 1 and core.counters.chunks_missing == 0
    assert not core.faults & Fault.CHUNK_GAP


def test_late_chunk_plays_from_now_repeats_are_ignored_a_gap_is_flagged() -> None:
    core = streaming()
    chunk(core, 0, 1, 1e-4 * np.arange(8))
    run(core, 1, 4)
    chunk(core, 1, 9, 1e-4 * np.arange(8, 16))
    assert not chunk(core, 1, 9, np.ones(8))  # repeated: ignored
    assert core.counters.chunks_duplicate == 1
    refs = run(core, 5, 12)
    np.testing.assert_allclose(refs[:, 0], 1e-4 * np.arange(4, 12), atol=1e-15)
    chunk(core, 2, 17, 1e-4 * np.arange(16, 24), arrival_ms=12)
    run(core, 13, 20)
    chunk(core, 4, 33, 1e-4 * np.arange(32, 40), end=True)  # chunk 3 not come: a gap, which it may still fill
    assert not core.faults & Fault.CHUNK_GAP and core.counters.chunks_missing == 0
    before = run(core, 21, 24)  # up to chunk 2's last sample (24 ms): the gap not played yet
    assert not core.faults & Fault.CHUNK_GAP and core.counters.chunks_missing == 0
    refs = np.vstack([before, run(core, 25, 45)])
    assert core.faults & Fault.CHUNK_GAP and core.counters.chunks_missing == 1  # played into it: it is missing
    np.testing.assert_allclose(refs[:4, 0], 1e-4 * np.arange(20, 24), atol=1e-15)
    np.testing.assert_allclose(refs[12:, 0], np.r_[1e-4 * np.arange(32, 40), [0.0039] * 5], atol=1e-15)
    assert np.all(np.diff(refs[3:13, 0]) > 0)  # across the gap: linear between the neighbours
    assert core.state is State.ARMED and core.counters.underruns == 0
    core.command(Command.START_STREAM, (10.0,), True, 46 * MS)
    chunk(core, 10, 40, 0.004 + 1e-4 * np.arange(8), arrival_ms=46)  # 40..45 ms were due by the last tick
    assert core.counters.samples_late == 6
    refs = run(core, 46, 47)
    np.testing.assert_allclose(refs[:, 0], [0.0046, 0.0047], atol=1e-15)  # played from the current time on


def test_an_underrun_is_a_controlled_stop_that_never_jumps_and_never_resumes() -> None:
    core = streaming()
    ramp = 0.2e-3 * np.arange(1, 41)  # 0.2 m/s for 40 ms
    for k in range(5):
        chunk(core, k, 1 + 8 * k, ramp[8 * k:8 * k + 8])
    states(core)
    refs = run(core, 1, 90)
    assert core.counters.underruns == 1 and core.faults & Fault.UNDERRUN
    assert states(core) == [State.STOPPING]  # dry before the end of the stream: a controlled stop
    v = np.diff(refs[:, 0]) * 1000
    at_rest = 40 + int(np.flatnonzero(v[40:] == 0.0)[0])  # decelerated to rest, then the return home begins
    dry = v[40:at_rest + 1]
    assert np.all(np.diff(dry) <= 1e-12) and np.all(np.diff(dry) >= -SURGE_DECELERATION * 1e-3 * (1 + 1e-9))
    assert np.all(np.abs(np.diff(v)) <= SURGE_DECELERATION * 1e-3 * (1 + 1e-9))  # no jump
    rest = refs[at_rest, 0]
    # samples that come after the underrun are not played: the plate does not jump to where the drive has got to
    assert not chunk(core, 5, 92, np.full(8, rest + 0.05), arrival_ms=90)
    refs = run(core, 91, 3000)
    assert np.all(np.abs(np.diff(refs[:, 0], 2)) * 1e6 <= SURGE_DECELERATION * (1 + 1e-6) + 1e-9)
    assert states(core) == [State.FAULTED] and core.faults & Fault.UNDERRUN
    np.testing.assert_allclose(refs[-1], np.zeros(6), atol=1e-15)  # home, then faulted (the drives braked)
    assert core.counters.underruns == 1 and core.counters.stops == 0


def test_a_chunk_beyond_the_buffer_capacity_is_refused_and_counted() -> None:
    core = streaming(buffer_capacity=20)
    assert chunk(core, 0, 1, np.zeros(8)) and chunk(core, 1, 9, np.zeros(8))
    assert not chunk(core, 2, 17, np.zeros(8))  # 24 samples do not fit 20
    assert core.counters.chunks_overflow == 1
    assert core.snapshot(0, np.zeros(6)).buffer_capacity == 20


def test_stream_silence_stops_the_table_home_and_faults() -> None:
    core = streaming()
    chunk(core, 0, 1, 2e-4 * np.ones(300))  # 300 ms buffered: the watchdog, not the buffer, ends it
    refs = run(core, 1, 100)
    assert core.state is State.STREAMING  # 100 ms of silence is allowed
    states(core)
    refs = run(core, 101, 2000)
    assert states(core) == [State.STOPPING, State.FAULTED]
    assert core.faults == Fault.STREAM_SILENT and core.counters.watchdog_stops == 1
    assert core.counters.underruns == 0
    np.testing.assert_allclose(refs[-1], np.zeros(6), atol=1e-15)
    assert core.tick(2001 * MS)[1]  # faulted: drives braked


def test_heartbeat_loss_stops_the_table() -> None:
    core = armed(pose=np.array([0.1, 0, 0, 0, 0, 0]))
    run(core, 1, 50)
    states(core)
    refs = run(core, 51, 3000, heartbeat=False)
    assert states(core) == [State.STOPPING, State.FAULTED]
    assert core.faults == Fault.HEARTBEAT_LOST
    np.testing.assert_allclose(refs[-1], np.zeros(6), atol=1e-15)
    assert refs[99, 0] == 0.1 and refs[101, 0] < 0.1  # ran at 150 ms: last heartbeat at 50 ms + 100 ms


def test_emergency_stop_brakes_at_once_and_arm_takes_over_where_the_plate_is() -> None:
    core = streaming()
    for k in range(20):
        chunk(core, k, 1 + 8 * k, 0.2e-3 * np.arange(8 * k + 1, 8 * k + 9))
    run(core, 1, 50)
    assert core.command(Command.EMERGENCY_STOP, (), False, 50 * MS) is Result.ACCEPTED
    assert core.tick(51 * MS)[1] and core.state is State.EMERGENCY_STOPPED
    assert core.counters.emergency_stops == 1 and core.snapshot(51 * MS, np.zeros(6)).buffer_depth == 0
    assert core.command(Command.HOME, (), True, 52 * MS) is Result.REJECTED
    core.observe(np.array([0.011, 0, 0, 0, 0, 0]))  # where the braked legs stopped
    core.command(Command.ARM, (), True, 60 * MS)
    reference, braked = core.tick(61 * MS)
    assert not braked and reference[0] == 0.011


# ----- actuators ----------------------------------------------------------------------------------------------


def test_leg_lag_follows_one_minus_exp_within_the_measurement_noise() -> None:
    tau, noise = 0.005, 2e-6
    act = Actuators(TABLE, 1e-3, ActuatorSettings(time_constant=tau, noise=noise), seed=3)
    target = np.array([0, 0, 0.001, 0, 0, 0])  # 1 mm heave: every leg well below its speed limit
    start, end = TABLE.leg_lengths(np.zeros(6)), TABLE.leg_lengths(target)
    step = act.step(np.tile(target, (40, 1)), np.zeros(40, dtype=bool))
    t = 1e-3 * np.arange(1, 41)
    response = 1 - np.exp(-t / tau)
    np.testing.assert_allclose(step.lengths, start + np.outer(response, end - start), rtol=0, atol=1e-15)
    expected = 0.001 * response
    measured = np.array([act.measure(step.lengths[i], step.poses[i])[2] for i in range(40)])
    np.testing.assert_allclose(step.poses[:, 2], expected, atol=3e-8)  # legs' lengths are not linear in heave
    assert np.abs(measured - expected).max() < 6 * noise  # the reading: within its noise
    assert np.abs(measured - expected).max() > 0.1 * noise  # and it does carry noise
    assert not step.setpoint_limited and not step.stroke_limited


def test_leg_speed_limit_and_forward_kinematics_consistency() -> None:
    act = Actuators(TABLE, 1e-3, ActuatorSettings(noise=0.0))
    target = np.array([0.02, -0.01, 0.05, 0.01, 0.03, 0.0])
    step = act.step(np.tile(target, (400, 1)), np.zeros(400, dtype=bool))
    speed = np.abs(np.diff(step.lengths, axis=0)).max() / 1e-3
    assert step.setpoint_limited and speed == pytest.approx(TABLE.geometry.leg_speed, rel=1e-9)
    np.testing.assert_allclose(TABLE.leg_lengths(step.poses), step.lengths, atol=1e-11)  # FK ∘ IK
    np.testing.assert_allclose(step.poses[-1], target, atol=1e-9)
    np.testing.assert_allclose(act.measure(step.lengths[-1], step.poses[-1]), target, atol=1e-12)  # no noise


def test_references_outside_the_envelope_are_clipped_and_flagged() -> None:
    act = Actuators(TABLE, 1e-3, ActuatorSettings(noise=0.0))
    step = act.step(np.tile([0.4, 0, 0, 0, 0, 0], (2000, 1)), np.zeros(2000, dtype=bool))
    assert step.setpoint_limited and step.poses[-1, 0] == pytest.approx(0.25, abs=1e-9)


def test_braked_legs_decelerate_to_rest() -> None:
    settings = ActuatorSettings(noise=0.0, brake_deceleration=20.0)
    act = Actuators(TABLE, 1e-3, settings)
    ramp = np.zeros((100, 6))
    ramp[:, 0] = 0.3e-3 * np.arange(1, 101)  # 0.3 m/s
    act.step(ramp, np.zeros(100, dtype=bool))
    step = act.step(np.tile(ramp[-1], (50, 1)), np.ones(50, dtype=bool))
    rates = np.abs(np.diff(step.lengths, axis=0)) / 1e-3
    assert np.all(np.diff(rates, axis=0) <= 1e-9) and np.all(np.diff(rates, axis=0) >= -20e-3 - 1e-9)
    assert rates[-1].max() == 0.0


# ----- accelerometers -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("beta", [0.0, math.radians(5), math.radians(-8)])
def test_specific_force_at_rest_carries_the_tilts_gravity(beta: float) -> None:
    pose = np.array([0.01, 0.02, -0.01, 0.0, beta, 0.0])
    track, accel = PlateTrack(1e-3, pose), Accelerometers([[0, 0, 0], [0.5, -0.3, 0.0]], 1e-3, noise=0.0)
    _, rates, window = track.advance(np.tile(pose, (5, 1)))
    force = accel.measure(window)
    np.testing.assert_allclose(force, np.broadcast_to([-G * math.sin(beta), 0, G * math.cos(beta)], force.shape),
                               atol=1e-9)
    np.testing.assert_allclose(rates, 0.0)


def test_specific_force_under_constant_acceleration_on_a_tilted_plate() -> None:
    beta, a = math.radians(5), 2.0
    t = 1e-3 * np.arange(50)
    poses = np.zeros((50, 6))
    poses[:, 0] = 0.5 * a * t**2
    poses[:, 4] = beta
    track = PlateTrack(1e-3, poses[0])
    centre, rates, window = track.advance(poses[1:])
    force = Accelerometers([[0.3, 0.1, 0.0]], 1e-3, noise=0.0).measure(window)[2:, 0]  # past the start
    expected = [a * math.cos(beta) - G * math.sin(beta), 0, a * math.sin(beta) + G * math.cos(beta)]
    np.testing.assert_allclose(force, np.broadcast_to(expected, force.shape), atol=1e-6)
    np.testing.assert_allclose(centre[1:], poses[1:-1], atol=0)  # one tick late
    np.testing.assert_allclose(rates[1:, 0], a * t[1:-1], atol=1e-12)  # central differences: exact here


def test_accelerometer_noise_is_seeded() -> None:
    window = np.zeros((12, 6))
    one = Accelerometers([[0, 0, 0]], 1e-3, noise=0.02, seed=5).measure(window)
    two = Accelerometers([[0, 0, 0]], 1e-3, noise=0.02, seed=5).measure(window)
    np.testing.assert_array_equal(one, two)
    assert 0.005 < np.std(one - [0, 0, G]) < 0.05


def test_bodies_on_the_command_line() -> None:
    s = parse_body("0.05x0.50@0.3,-0.1")
    assert (s.body.b, s.body.h, s.x, s.y) == (0.05, 0.5, 0.3, -0.1)
    assert (parse_body("0.1x0.4").x, parse_body("0.1x0.4").y) == (0.0, 0.0)
    with pytest.raises(ValueError, match="BxH@X,Y"):
        parse_body("0.1x0.4@1")
    full = parse_body("0.039x0.2@0,-0.15;depth=0.081;mass=0.36;mu=0.5")
    assert (full.body.depth, full.body.mass, full.friction, full.y) == (0.081, 0.36, 0.5, -0.15)
    with pytest.raises(ValueError, match=r"unknown option.*colour"):
        parse_body("0.1x0.4;colour=1")
    with pytest.raises(ValueError, match="mass=M"):
        parse_body("0.1x0.4;mass=heavy")


@pytest.mark.integration
def test_the_emulator_asks_for_a_signing_key_only_on_transports_that_sign(tmp_path: Path) -> None:
    """``rig emulate`` (registered on an app of its own here: it becomes ``python -m sim_table``) with no key in the
    environment: canopen:// listens (CAN has no authentication); mavlink:// and zenoh:// are refused, naming the key
    option and variable."""
    code = ("import typer\nfrom rig.cli import emulate as cli_emulate\napp = typer.Typer()\ncli_emulate.register(app)\n"
            "@app.callback()\ndef main() -> None: pass\napp()")
    env = {name: value for name, value in os.environ.items() if name != KEY_ENV}
    counters = tmp_path / "counters.json"
    proc = subprocess.Popen([sys.executable, "-c", code, "emulate", "--listen",
                             f"canopen://emulate-{uuid.uuid4().hex}?interface=virtual", "--counters", str(counters)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert "listening on canopen://emulate-" in line, line + proc.stderr.read()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        proc.kill()
    assert json.loads(counters.read_text())["state"] == "idle"
    for url in ("mavlink://127.0.0.1:0", "zenoh://127.0.0.1:0/table"):
        refused = subprocess.run([sys.executable, "-c", code, "emulate", "--listen", url], capture_output=True,
                                 text=True, env=env, timeout=60)
        assert refused.returncode == 2 and "listening" not in refused.stderr
        assert "needs the rig's signing key: give --key-file FILE or set SHAKETABLE_MAVLINK_KEY" in refused.stderr


# ----- virtual time ------------------------------------------------------------------------------------------


@pytest.mark.integration
def test_virtual_time_never_plays_a_tick_whose_setpoint_has_not_come() -> None:
    """``--speed max``: the clock runs ahead only as far as the buffered setpoints reach, holds there without an
    underrun (and reports where it holds), runs to the stream's end once END_OF_STREAM came, and plays the same
    reference as the samples say; the accelerometers count every tick once."""
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), speed=math.inf))
    try:
        core = emulator.core
        assert emulator.virtual and core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
        assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
        samples = np.zeros((300, 6))
        samples[:, 0] = 0.01 * np.sin(np.linspace(0.0, math.pi, 300))
        start = 50_000_000  # the first sample due 50 ms on
        for _ in range(20):  # nothing buffered: the clock holds at 0
            core.heartbeat(0)
            assert emulator.step_virtual(0) == 0
        assert emulator.controller_time(0) == 0 and core.state is State.STREAMING
        core.chunk(0, start, 1_000_000, samples[:100], False, True, 0)
        ran = sum(emulator.step_virtual(0) for _ in range(20))
        last = start + 99 * 1_000_000
        assert emulator.controller_time(0) == last and ran == last // 1_000_000  # up to the last sample, no further
        assert core.counters.underruns == 0 and core.state is State.STREAMING
        core.heartbeat(0)
        core.chunk(1, start + 100 * 1_000_000, 1_000_000, samples[100:], True, True, 0)
        while core.state is State.STREAMING:
            emulator.step_virtual(0)
        end = start + 299 * 1_000_000
        assert core.counters.streams_completed == 1 and core.counters.underruns == 0
        assert emulator.controller_time(0) >= end and core.counters.samples_late == 0
        np.testing.assert_allclose(emulator.actuators.pose[0], samples[-1, 0], atol=1e-4)  # followed the samples
        sent = emulator.endpoint.counters_dict()
        assert sent["status_sent"] >= emulator.controller_time(0) // 20_000_000  # 50 Hz of controller time
    finally:
        emulator.close()


@pytest.mark.integration
def test_virtual_time_cuts_its_batches_when_a_batch_takes_long_in_wall_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """A host too busy for 80 ticks a batch: with every tick made to take at least 2 ms of wall time (a sleep,
    which never ends early), the batch after a full one of ``VIRTUAL_BATCH`` ticks runs at most
    ``VIRTUAL_BATCH_WALL_NS`` / 2 ms = 25 ticks (its statuses go out at its end), each later one at least one; the
    stream still plays to its end, every tick once, without an underrun."""
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), speed=math.inf))
    slow_tick_s = 0.002
    batch = emulator._batch

    def slow_batch(times: np.ndarray) -> None:
        time.sleep(slow_tick_s * len(times))
        batch(times)

    try:
        core = emulator.core
        assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
        assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
        core.heartbeat(0)
        core.chunk(0, 10_000_000, 1_000_000, np.zeros((400, 6)), True, True, 0)
        assert emulator.step_virtual(0) == VIRTUAL_BATCH  # nothing measured yet: a full batch
        monkeypatch.setattr(emulator, "_batch", slow_batch)
        ran = [emulator.step_virtual(0)]  # the first slow batch, sized before a slow one was seen
        while core.state is State.STREAMING:
            core.heartbeat(0)
            ran.append(emulator.step_virtual(0))
        cap = VIRTUAL_BATCH_WALL_NS // round(slow_tick_s * 1e9)
        assert len(ran) > 2 and max(ran[1:]) <= cap and min(ran[1:]) >= 1
        assert core.counters.streams_completed == 1 and core.counters.underruns == 0
        assert emulator.controller_time(0) >= 10_000_000 + 399 * 1_000_000
    finally:
        emulator.close()


def test_batcher_numbers_each_sources_batches_and_continues_its_time() -> None:
    """The endpoints' batching of evenly spaced samples: full batches at once, each source its own numbering and
    time line (its first piece's start, then contiguous), the rest on flush, the numbering going on after it."""
    batcher = Batcher(4)
    assert batcher.add(0, 10, 5, np.arange(3.0)) == []
    assert batcher.add(1, 0, 7, np.zeros((2, 3))) == []
    full = batcher.add(0, 999, 5, np.arange(3.0, 10.0))  # a later piece's own start is not looked at
    assert [(b.source, b.seq, b.t_start_ns, b.spacing_ns) for b in full] == [(0, 0, 10, 5), (0, 1, 30, 5)]
    np.testing.assert_array_equal(np.concatenate([b.samples for b in full]), np.arange(8.0))
    rest = batcher.flush()
    assert [(b.source, b.seq, b.t_start_ns, len(b.samples)) for b in rest] == [(0, 2, 50, 2), (1, 0, 0, 2)]
    assert batcher.flush() == []
    after = batcher.add(0, 0, 5, np.arange(4.0))
    assert [(b.source, b.seq, b.t_start_ns) for b in after] == [(0, 3, 60)]


@pytest.mark.integration
def test_the_bodies_tilt_sensors_sample_every_fifth_tick_on_a_contiguous_grid(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two bodies, virtual time, a 0.7 s stream of a gentle surge: each body's angles reach the endpoint at
    ``TILT_RATE`` (every 5th 1 kHz tick), on the 5 ms grid of controller time (dated as the accelerometer samples:
    one tick late), each call continuing the previous one, every tick on the grid once; the bodies stand (|θ| small,
    not exactly 0: the contact is compliant); full batches of ``TILT_PER_BATCH`` are counted as sent."""
    specimens = (parse_body("0.05x0.50@0.4,0"), parse_body("0.15x0.45@-0.4,0"))
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), speed=math.inf,
                                       specimens=specimens))
    calls: list[tuple[int, int, int, np.ndarray]] = []
    forward = emulator.endpoint.add_tilt
    monkeypatch.setattr(emulator.endpoint, "add_tilt", lambda body, t0, spacing, angles: (
        calls.append((body, t0, spacing, np.array(angles))), forward(body, t0, spacing, angles)))
    try:
        core = emulator.core
        assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
        assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
        samples = np.zeros((700, 6))
        samples[:, 0] = 0.002 * np.sin(np.linspace(0.0, 2 * math.pi, 700))
        core.heartbeat(0)
        core.chunk(0, 10_000_000, 1_000_000, samples, True, True, 0)
        while core.state is State.STREAMING:
            core.heartbeat(0)  # the host's, as a link's thread sends them: the watchdog counts host time
            emulator.step_virtual(0)
        assert core.faults == Fault(0)  # played to its end, not stopped
        plate_time = emulator.controller_time(0) - emulator.tick_ns  # the last tick's plate time
        counters = emulator.endpoint.counters_dict()
    finally:
        emulator.close()
    spacing = round(1e9 / TILT_RATE)
    assert emulator.tilt_spacing_ns == spacing == 5 * MS
    for body in (0, 1):
        mine = [c for c in calls if c[0] == body]
        assert {c[2] for c in mine} == {spacing}
        times = np.concatenate([t0 + spacing * np.arange(len(angles)) for _, t0, _, angles in mine])
        np.testing.assert_array_equal(times, spacing * np.arange(1, plate_time // spacing + 1))  # from 5 ms on
        angles = np.concatenate([c[3] for c in mine])
        assert 0 < np.abs(angles).max() < 1e-3
    assert counters["tilt_samples_sent"] == 2 * (len(times) // TILT_PER_BATCH) * TILT_PER_BATCH
    assert counters["tilt_batches_sent"] == 2 * (len(times) // TILT_PER_BATCH)


def test_speed_max_parses_and_canopen_refuses_it(tmp_path: Path) -> None:
    key = tmp_path / "rig.key"
    write_signing_key(key)
    config, _, _ = parse_args(["--listen", "zenoh://127.0.0.1:0/t", "--speed", "max", "--key-file", str(key)])
    assert math.isinf(config.speed)
    with pytest.raises(SystemExit):
        parse_args(["--listen", "mavlink://127.0.0.1:0", "--speed", "fast"])
    with pytest.raises(ValueError, match="CANopen has no virtual time"):
        EmulatorConfig(listen="canopen://x?interface=virtual", speed=math.inf)


@pytest.mark.integration
def test_an_underrun_mid_drive_measures_no_spike_on_the_plate(monkeypatch: pytest.MonkeyPatch) -> None:
    """The 15–33 g one-sample spikes of runs that underran: the buffer ran dry mid-drive, the reference held, and
    the samples that came late resumed the drive where it had got to — a jump the legs followed at their speed
    limit. Now the underrun is a controlled stop and late samples are not played: the plate's measured fall-line
    acceleration stays within the drive's own and Table IV's deceleration (plus the sensor's noise)."""
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32)))
    measured: list[np.ndarray] = []
    monkeypatch.setattr(emulator.endpoint, "add_accel",
                        lambda sensor, t0, spacing, samples: measured.append(np.array(samples)))
    try:
        core = emulator.core
        assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
        assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
        t = np.arange(3000) * 1e-3
        samples = np.zeros((3000, 6))
        samples[:, 0] = 0.05 * (1 - np.cos(2 * math.pi * t))  # 1 Hz, peak 1.97 m/s², starting at rest
        core.chunk(0, MS, MS, samples[:600], False, True, 0)  # 0.6 s buffered, then a stall of the host
        for k in range(300):  # 3 s in batches of 10 ticks, heartbeats going on
            times = (10 * k + 1 + np.arange(10, dtype=np.int64)) * MS
            core.heartbeat(int(times[0]))
            if k == 100:  # the late rest of the drive arrives 1 s in: its due samples are past
                core.chunk(1, 601 * MS, MS, samples[600:], True, True, int(times[0]))
            emulator._batch(times)
    finally:
        emulator.close()
    assert core.counters.underruns == 1 and core.faults & Fault.UNDERRUN
    fx = np.concatenate(measured)[:, 0]
    drive_peak = float(np.abs(np.gradient(np.gradient(samples[:, 0], 1e-3), 1e-3)).max())
    bound = max(drive_peak, SURGE_DECELERATION) * 1.05 + 5 * emulator.config.accel_noise
    assert np.abs(fx).max() <= bound, (np.abs(fx).max(), bound)


@pytest.mark.integration
def test_the_counters_say_where_each_tick_s_cpu_time_went() -> None:
    """Two bodies, virtual time, a 0.4 s stream: ``timing.profile_cpu_us_per_tick`` splits the tick thread's CPU
    time by stage (``sim_table/tick_profile.py``): every stage that ran is there, MuJoCo's steps among them, and
    together they account for the tick thread's CPU time per tick, the network's service after a batch with it."""
    specimens = (parse_body("0.05x0.50@0.4,0"), parse_body("0.15x0.45@-0.4,0"))
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), speed=math.inf,
                                       specimens=specimens))
    try:
        core = emulator.core
        assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
        assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
        core.heartbeat(0)
        core.chunk(0, 10_000_000, 1_000_000, np.zeros((400, 6)), True, True, 0)
        while core.state is State.STREAMING:
            core.heartbeat(0)
            emulator.step_virtual(0)
        timing = emulator.counters()["timing"]
    finally:
        emulator.close()
    profile = timing["profile_cpu_us_per_tick"]
    assert set(profile) == {"controller", "servo", "plate", "physics", "impacts", "specimens", "transport", "total"}
    assert all(profile[stage] > 0 for stage in profile), profile
    assert profile["total"] == pytest.approx(sum(v for k, v in profile.items() if k != "total"))
    assert timing["tick_cpu_mean_us"] <= profile["total"] <= 1.25 * timing["tick_cpu_mean_us"], timing
