"""Issue 42, item 1, in process: the setpoint check the host and the controller share (``analysis.table.setpoints``),
the controller core refusing a signed chunk it must not play (a reason, a controlled stop, never a jump), and the
host's refusal to stream such a trajectory (``drivers.controller.playable_poses``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.table.model import TableModel
from analysis.table.setpoints import RATE_ALLOWANCE, check_setpoints
from drivers.controller import SetpointError, TableError, playable_poses
from sim_table.controller import Command, ControllerCore, Fault, Refused, Result, State, StateChange

MS = 1_000_000
TABLE = TableModel()
SURGE_DECELERATION = TABLE.limits.surge.acceleration  # m/s², Table IV


def poses(n: int = 8, **columns: float) -> np.ndarray:
    """``n`` poses at rest at home, with the named columns (surge, sway, heave, roll, pitch, yaw) set."""
    out = np.zeros((n, 6))
    for name, value in columns.items():
        out[:, ("surge", "sway", "heave", "roll", "pitch", "yaw").index(name)] = value
    return out


def hostile(case: str) -> np.ndarray:
    """Eight 1 ms samples of a slow surge ramp, one of them (or a step) made hostile."""
    samples = poses()
    samples[:, 0] = 1e-4 * np.arange(8)  # 0.1 m/s
    if case == "nan":
        samples[3, 2] = math.nan
    elif case == "inf":
        samples[3, 2] = math.inf
    elif case == "float32 max":
        samples[3, 2] = 3.4e38
    elif case == "envelope":
        samples[3, 2] = 0.3  # heave beyond ±0.18 m (and in no leg's stroke trouble first: checked per sample)
    elif case == "rate":
        samples[3:, 0] += 0.01  # a 10 mm step in 1 ms: 10 m/s
    return samples


CASES = {"nan": ("finite", "heave nan"), "inf": ("finite", "heave inf"),
         "float32 max": ("envelope", "heave 3.4e+38 m outside [-0.1800, 0.1800] m"),
         "envelope": ("envelope", "heave 0.3 m outside [-0.1800, 0.1800] m"),
         "rate": ("rate", "from the sample before, beyond its speed 0.9000 m/s")}


# ----- the check ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES)
def test_the_check_names_the_sample_and_the_limit(case: str) -> None:
    kind, detail = CASES[case]
    problem = check_setpoints(TABLE, hostile(case), 1e-3)
    assert problem is not None and problem.kind == kind and problem.sample == 3
    assert detail in problem.message() and problem.message().startswith("sample 3: ")


def test_a_drive_inside_the_limits_passes_and_the_allowances_are_what_they_say() -> None:
    t = np.arange(4001) * 1e-3
    drive = poses(len(t), pitch=math.radians(5))
    drive[:, 0] = 0.2 * np.sin(2 * math.pi * 0.3 * t)  # 0.38 m/s peak, inside the envelope
    assert check_setpoints(TABLE, drive, 1e-3) is None
    assert check_setpoints(TABLE, poses(2, heave=0.18 + 5e-6), 1e-3) is None  # within POSITION_ALLOWANCE
    assert check_setpoints(TABLE, poses(2, heave=0.18 + 2e-5), 1e-3).kind == "envelope"
    step = TABLE.leg_lengths(poses(1, heave=1e-3))[0, 0] - TABLE.leg_lengths(poses(1))[0, 0]  # leg 1 per mm heave
    speed = TABLE.geometry.leg_speed
    slow, fast = (speed * (1 + share) * 1e-3 / step * 1e-3 for share in (RATE_ALLOWANCE / 2, 2 * RATE_ALLOWANCE))
    assert check_setpoints(TABLE, np.vstack([poses(1), poses(1, heave=slow)]), 1e-3) is None
    assert check_setpoints(TABLE, np.vstack([poses(1), poses(1, heave=fast)]), 1e-3).kind == "rate"


def test_the_steps_from_the_pose_before_and_to_the_pose_after_are_checked() -> None:
    still = poses(4)
    moved = poses(1, surge=0.01)[0]
    assert check_setpoints(TABLE, still, 1e-3, previous=(moved, 1.0)) is None  # 10 mm in 1 s
    assert check_setpoints(TABLE, still, 1e-3, previous=(moved, 1e-3)).sample == 0
    assert check_setpoints(TABLE, still, 1e-3, following=(moved, 1e-3)).sample == 4
    assert check_setpoints(TABLE, still, 1e-3, previous=(moved, 0.0)) is None  # no time between them: not a step


def test_a_leg_out_of_its_stroke_is_named() -> None:
    turned = poses(1, heave=0.18, yaw=1.1)  # yaw has no limit of its own: the legs' stroke bounds it
    problem = check_setpoints(TABLE, turned, 1e-3)
    assert problem is not None and problem.kind == "stroke"
    assert problem.detail == "leg 2 length 3.0167 m outside its stroke [1.6000, 2.8500] m"


# ----- the controller core ------------------------------------------------------------------------------------


def streaming_core() -> ControllerCore:
    core = ControllerCore(TABLE)
    assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
    assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
    core.take_events()
    return core


def run(core: ControllerCore, start_ms: int, stop_ms: int) -> np.ndarray:
    """Ticks start..stop (ms, inclusive) with a heartbeat before each, ideal actuators; the references (n, 6)."""
    out = []
    for ms in range(start_ms, stop_ms + 1):
        core.heartbeat(ms * MS)
        reference, braked = core.tick(ms * MS)
        if not braked:
            core.observe(reference)
        out.append(reference.copy())
    return np.array(out)


def send(core: ControllerCore, seq: int, t0_ms: int, samples: np.ndarray, arrival_ms: int, *, end: bool = False,
         signed: bool = True) -> bool:
    return core.chunk(seq, t0_ms * MS, MS, samples, end, signed, arrival_ms * MS)


def ramp(start: float, n: int = 8) -> np.ndarray:
    """``n`` surge samples 1 ms apart rising at 0.2 m/s from ``start`` [m]."""
    out = poses(n)
    out[:, 0] = start + 2e-4 * np.arange(n)
    return out


@pytest.mark.parametrize("case", CASES)
def test_a_signed_chunk_the_table_must_not_play_is_refused_mid_stream_with_a_controlled_stop(case: str) -> None:
    core = streaming_core()
    for k in range(4):  # 32 ms of a 0.2 m/s ramp, then the hostile chunk while it plays
        assert send(core, k, 1 + 8 * k, ramp(2e-4 * 8 * k), arrival_ms=0)
    moving = run(core, 1, 20)
    bad = hostile(case) + np.array([ramp(0.0064)[0, 0], 0, 0, 0, 0, 0])
    assert not send(core, 4, 33, bad, arrival_ms=20)
    events = core.take_events()
    refused = [e for e in events if isinstance(e, Refused)]
    detail = CASES[case][1]
    assert len(refused) == 1 and refused[0].seq == 4 and refused[0].t_ns == 20 * MS
    assert refused[0].reason.startswith("chunk 4 sample 3: ") and detail in refused[0].reason
    assert [e.new for e in events if isinstance(e, StateChange)] == [State.STOPPING]
    assert core.faults & Fault.SETPOINT_REFUSED and core.counters.chunks_refused == 1
    assert core.counters.last_refusal == refused[0].reason
    stop = run(core, 21, 3000)
    refs = np.vstack([moving, stop])
    assert np.isfinite(refs).all() and np.abs(refs[:, 0]).max() < 0.01  # none of the refused samples played
    v = np.diff(refs[:, 0]) * 1e3
    assert np.all(np.abs(np.diff(v)) * 1e3 <= SURGE_DECELERATION * (1 + 1e-6) + 1e-9)  # no jump: decelerates
    assert core.state is State.FAULTED and core.tick(3001 * MS)[1]  # home, then faulted (braked)
    np.testing.assert_allclose(refs[-1], np.zeros(6), atol=1e-12)
    assert not send(core, 5, 3100, ramp(0.0), arrival_ms=3001)  # a stream refused never resumes
    assert core.command(Command.ARM, (), True, 3002 * MS) is Result.ACCEPTED and not core.faults  # ARM clears it


def test_an_unsigned_hostile_chunk_is_refused_for_its_signature_and_does_not_stop_the_table() -> None:
    core = streaming_core()
    assert not send(core, 0, 1, hostile("nan"), arrival_ms=0, signed=False)
    assert core.state is State.STREAMING and core.faults == Fault.UNSIGNED_COMMAND
    assert core.counters.chunks_refused == 0 and core.counters.refused_commands == 1


def test_a_first_chunk_far_from_the_held_pose_is_a_step_and_refused() -> None:
    core = streaming_core()  # holds home since START_STREAM at 0 ms
    assert not send(core, 0, 5, poses(8, surge=0.1), arrival_ms=0)  # 0.1 m in 5 ms: 20 m/s
    assert "sample 0: leg" in core.counters.last_refusal and core.state is State.STOPPING


def test_a_gap_filled_late_is_checked_against_both_neighbours() -> None:
    core = streaming_core()
    assert send(core, 0, 1, ramp(0.0), arrival_ms=0)
    assert send(core, 2, 17, ramp(0.0032), arrival_ms=0)
    filler = ramp(0.0016)
    filler[-1, 0] = 0.0016 + 0.005  # its last sample 5 mm ahead of the next chunk's first, 2 ms later: 2.5 m/s
    assert not send(core, 1, 9, filler, arrival_ms=1)
    assert core.counters.last_refusal.startswith("chunk 1 sample 7: ") and core.state is State.STOPPING


# ----- the host -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES)
def test_the_host_refuses_to_stream_such_a_trajectory_naming_the_sample(case: str) -> None:
    with pytest.raises(SetpointError) as raised:
        playable_poses("mavlink://127.0.0.1:1", TABLE, hostile(case), 1e-3, (np.zeros(6), 1.0))
    message = str(raised.value)
    assert message.startswith("mavlink://127.0.0.1:1: trajectory not sent: sample 3 (t = 0.003 s): ")
    assert CASES[case][1] in message and isinstance(raised.value, TableError)


def test_the_host_checks_the_blend_from_the_held_pose() -> None:
    far = poses(1, surge=0.2)[0]
    assert playable_poses("u", TABLE, poses(4), 1e-3, (far, 1.0)).shape == (4, 6)  # 0.2 m over the 1 s lead
    with pytest.raises(SetpointError, match=r"sample 0 \(t = 0\.000 s\): leg .* \(from the pose the table holds\)"):
        playable_poses("u", TABLE, poses(4), 1e-3, (far, 0.05))
    with pytest.raises(ValueError, match=r"shape \(N, 6\)"):
        playable_poses("u", TABLE, np.zeros((3, 5)), 1e-3, None)
