"""The servo-hydraulic legs (sim_table.dynamics) against closed forms: the oil-column frequency from the cylinder's
dimensions, the closed loop's transfer function (continuous, and the sampled loop built with scipy.signal)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.table.dynamics import TableDynamics
from analysis.table.model import TableModel, TableModelError
from sim_table.actuators import ActuatorSettings, _first_order_lag
from sim_table.dynamics import ServoActuators, _run, make_actuators

DT = 1e-3
TABLE = TableModel()


def _sine_fit(t: np.ndarray, y: np.ndarray, omega: float) -> complex:
    """Complex amplitude of the ω-component of y (least squares on cos, sin, offset)."""
    basis = np.column_stack([np.cos(omega * t), np.sin(omega * t), np.ones_like(t)])
    (c, s, _), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return complex(c, -s)


def test_oil_column_frequency_from_the_cylinder():
    """Merritt's ω_h = sqrt(4βA²/(V_t m)) written out from bore, stroke, β, line volume and masses."""
    d = TableDynamics(bore=0.05, bulk_modulus=1.2e9, line_volume=0.001, plate_mass=1200.0, piston_mass=25.0)
    stroke, payload = 1.25, 60.0
    area = math.pi * 0.05**2 / 4
    volume = area * stroke + 0.001
    mass = 25.0 + (1200.0 + 60.0) / 6
    expected = math.sqrt(4 * 1.2e9 * area**2 / (volume * mass))
    assert d.oil_column_frequency(stroke, payload) == pytest.approx(expected, rel=1e-12)
    # two chambers of volume V = V_t / 2 each a spring βA²/V in parallel: the same
    assert expected == pytest.approx(math.sqrt(2 * (1.2e9 * area**2 / (volume / 2)) / mass), rel=1e-12)


def test_the_simulated_column_rings_at_the_damped_oil_column_frequency():
    """The open plant (valve closed) released from a compressed column oscillates at ω_h·sqrt(1 − ζ²)."""
    legs = ServoActuators(TABLE, DT, payload=100.0)
    wh, zeta = legs.omega_h, legs.dynamics.damping_ratio
    state = np.array([0.0, 1e-3, 2.0, 0.0])
    ys = []
    for _ in range(2000):
        state = legs._ad @ state
        ys.append(state[2] - 2.0)
    ys = np.array(ys)
    t = DT * np.arange(1, len(ys) + 1)
    rises = t[1:][(ys[:-1] < ys[-1]) & (ys[1:] >= ys[-1])]  # crossings of the final level, upwards
    period = float(np.mean(np.diff(rises[:3])))
    assert 2 * math.pi / period == pytest.approx(wh * math.sqrt(1 - zeta**2), rel=5e-3)
    g = TABLE.geometry
    assert legs.omega_h == pytest.approx(TableDynamics().oil_column_frequency(g.leg_max - g.leg_min, 100.0))


@pytest.mark.parametrize("hz", [0.5, 3.0, 8.0, 12.0, 16.0, 30.0])
def test_simulated_legs_follow_the_closed_loop_transfer_function(hz):
    """Sine on every leg's command through the numba loop: the steady response matches the sampled loop's dlti
    exactly and the continuous H(s) within 2 % and one tick's phase (the sampled controller's hold and
    backward-difference feed-forward)."""
    from scipy import signal

    legs = ServoActuators(TABLE, DT)
    d, g = legs.dynamics, TABLE.geometry
    omega = 2 * math.pi * hz
    n = round(6.0 / DT)
    t = DT * np.arange(n)
    amplitude = 0.1 / omega  # 0.1 m/s peak speed, far from the valve's saturation
    command = 2.2 + amplitude * np.sin(omega * t)
    commanded = np.repeat(command[:, None], 6, axis=1)
    state = np.zeros((6, 4))
    state[:, 2] = 2.2
    out = np.empty_like(commanded)
    saturated = _run(legs._ad, legs._bd, state, np.full(6, 2.2), np.zeros(6), commanded, np.zeros(n, bool),
                     np.zeros(6, bool), d.loop_gain, d.velocity_feedforward, DT, g.leg_speed, 0.0, g.leg_min,
                     g.leg_max, out)
    assert not saturated
    steady = t > 3.0
    by_tick = _sine_fit(t[steady], out[steady, 0], omega) / _sine_fit(t[steady], command[steady], omega)
    _, discrete = legs.discrete_closed_loop().freqresp([omega * DT])
    assert by_tick == pytest.approx(discrete[0], rel=1e-6)
    _, continuous = signal.freqresp(legs.closed_loop(), [omega])
    assert abs(by_tick) == pytest.approx(abs(continuous[0]), rel=0.02)
    assert abs(np.angle(by_tick / continuous[0])) < omega * DT + math.radians(0.5)  # sampling: within one tick


def test_plate_shows_the_oil_column_resonance():
    """A surge sine through the legs and the kinematics: followed at 0.5 Hz, amplified near ω_h, filtered above."""
    gains = {}
    for hz in (0.5, 11.0, 30.0):
        legs = ServoActuators(TABLE, DT)
        omega = 2 * math.pi * hz
        t = DT * np.arange(int(4.0 / DT))
        reference = np.zeros((len(t), 6))
        reference[:, 0] = (0.05 / omega) * np.sin(omega * t)
        poses = np.concatenate([legs.step(reference[i:i + 50], np.zeros(50, bool)).poses
                                for i in range(0, len(t), 50)])
        steady = t > 2.0
        gains[hz] = abs(_sine_fit(t[steady], poses[steady, 0], omega) / _sine_fit(t[steady], reference[steady, 0],
                                                                                   omega))
    assert gains[0.5] == pytest.approx(1.0, abs=0.03)
    assert gains[11.0] > 1.5
    assert gains[30.0] < 0.7


def test_brakes_bring_the_legs_to_rest_and_limits_are_flagged():
    legs = ServoActuators(TABLE, DT, ActuatorSettings(noise=0.0))
    reference = np.zeros((300, 6))
    reference[:, 0] = np.linspace(0, 0.1, 300)
    legs.step(reference, np.zeros(300, bool))
    moving = legs.lengths.copy()
    held = legs.step(np.zeros((1000, 6)), np.ones(1000, bool))
    assert np.abs(np.diff(held.lengths[-50:], axis=0)).max() < 1e-9  # at rest
    assert np.abs(held.lengths[-1] - moving).max() < 0.05  # braked near where it was, not sent home
    assert np.array_equal(held.commanded, held.lengths)
    far = np.zeros((5, 6))
    far[:, 0] = 1.0  # beyond surge's 0.25 m
    assert legs.step(far, np.zeros(5, bool)).setpoint_limited
    jump = np.zeros((5, 6))
    jump[:, 2] = 0.17
    assert legs.step(jump, np.zeros(5, bool)).setpoint_limited  # a 0.17 m heave step saturates the valves
    assert np.allclose(legs.measure(legs.lengths, legs.pose), legs.pose, atol=1e-12)


def test_make_actuators_and_the_rig_toml_section(tmp_path):
    assert type(make_actuators("servo", TABLE, DT, ActuatorSettings(), payload=50.0)).__name__ == "ServoActuators"
    assert type(make_actuators("lag", TABLE, DT, ActuatorSettings())).__name__ == "Actuators"
    with pytest.raises(ValueError, match="unknown dynamics"):
        make_actuators("rigid", TABLE, DT, ActuatorSettings())
    path = tmp_path / "rig.toml"
    path.write_text("[dynamics]\nbore_m = 0.05\nloop_gain_per_s = 20\n")
    model = TableModel.from_toml(path)
    assert model.dynamics == TableDynamics(bore=0.05, loop_gain=20.0)
    assert TableModel.from_dict(model.to_dict()) == model
    assert "dynamics" not in TableModel().to_dict()  # the default stays out of existing files
    path.write_text("[table]\ncontroller_rate_hz = 1000\n\n[dynamics]\ndamping_ratio = 1.5\n")
    with pytest.raises(TableModelError, match=r"rig.toml:5: dynamics.damping_ratio: .*< 1"):
        TableModel.from_toml(path)
    path.write_text("[dynamics]\nbore_mm = 40\n")
    with pytest.raises(TableModelError, match=r"rig.toml:2: dynamics.bore_mm: unknown key"):
        TableModel.from_toml(path)


def test_the_emulator_chooses_its_legs_by_name():
    """``--dynamics servo`` gives the emulator servo legs loaded by its specimens' mass; the default stays the lag."""
    import uuid

    from sim_table.actuators import Actuators
    from sim_table.process import Emulator, parse_args

    listen = f"canopen://issue12-{uuid.uuid4().hex[:8]}?interface=virtual"
    config, _, _ = parse_args(["--listen", listen, "--dynamics", "servo", "--body", "0.1x0.5@0.3,0;mass=20"])
    assert config.dynamics == "servo"
    emulator = Emulator(config)
    try:
        assert isinstance(emulator.actuators, ServoActuators)
        assert emulator.actuators.payload == pytest.approx(20.0)
    finally:
        emulator.close()
    assert parse_args(["--listen", listen])[0].dynamics == "lag"
    emulator = Emulator(parse_args(["--listen", listen])[0])
    try:
        assert isinstance(emulator.actuators, Actuators)
    finally:
        emulator.close()


def test_the_lag_legs_filter_is_scipy_s_first_order_filter() -> None:
    """The "lag" legs' batch filter against scipy.signal.lfilter of y = (1 − a)·c + a·y[−1] with its initial state,
    on random commands, a non-contiguous start and a read-only command array."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(7)
    a = math.exp(-0.001 / 0.005)
    commanded = rng.normal(size=(41, 6))
    start = rng.normal(size=(6, 2))[:, 0]
    expected = lfilter([1.0 - a], [1.0, -a], commanded, axis=0, zi=(a * start)[None, :])[0]
    commanded.flags.writeable = False
    actuators = make_actuators("lag", TABLE, 0.001, ActuatorSettings())
    got = actuators._filter(commanded, start)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)
    assert _first_order_lag(np.zeros((0, 6)), np.zeros(6), a).shape == (0, 6)
