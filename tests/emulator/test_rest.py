"""The emulator brought back to its power-up state between two tests that share it (``Emulator.rest``, SIGUSR1;
``tests/helpers/tables.py``): what a test leaves behind — a latched fault, a plate away from home, an owner, counts
— is gone, and the counters of what it did are handed over."""

from __future__ import annotations

import secrets
import uuid

import numpy as np
import pytest

from sim_table.controller import Command, Fault, Result, State
from sim_table.process import Emulator, EmulatorConfig


@pytest.mark.integration  # the MAVLink endpoint binds a UDP socket
def test_rest_hands_over_the_counters_and_leaves_the_table_as_at_power_up() -> None:
    emulator = Emulator(EmulatorConfig(listen="mavlink://127.0.0.1:0", key=secrets.token_bytes(32)))
    try:
        core = emulator.core
        assert [core.command(Command.ARM, (), True, t) for t in (0, 1)] == [Result.ACCEPTED] * 2
        core.raise_fault(Fault.DRIVE, 2)
        emulator.actuators.pose = np.full(6, 0.01)  # the plate where the test left it, away from home
        emulator._last_centre = np.full(6, 0.01)
        emulator.endpoint._ownership.claim("a host", "a host", 0, 0.0)  # type: ignore[attr-defined]
        emulator.endpoint.counters.packets_received = 7  # type: ignore[attr-defined]
        window = np.zeros((3, 6))
        fresh_noise = emulator.accelerometers.measure(window)
        emulator.accelerometers.measure(window)  # the noise drawn on
        emulator.accelerometers.sigma[0] += 0.5  # made noisy (--accel-noisy), as a test may leave it

        counters = emulator.rest()

        assert counters["commands_accepted"] == 2 and counters["faults_raised"] == {"DRIVE": 1}
        assert counters["link"]["packets_received"] == 7 and counters["link"]["claims_granted"] == 1
        after = emulator.counters()
        assert after["commands_accepted"] == 0 and after["faults_raised"] == {} and after["faults"] == []
        assert after["link"]["packets_received"] == 0 and after["link"]["claims_granted"] == 0
        assert emulator.core is not core and emulator.core.state is State.IDLE and not emulator.core.faults
        assert emulator.core.first_stream_ns is None
        np.testing.assert_array_equal(emulator._last_centre, np.zeros(6))
        assert np.abs(emulator.actuators.pose).max() == 0.0
        assert emulator.endpoint._ownership.owner(0) is None  # type: ignore[attr-defined]
        np.testing.assert_array_equal(emulator.accelerometers.measure(window), fresh_noise)  # as at power-up
    finally:
        emulator.close()


def test_rest_is_refused_on_canopen_with_what_and_why() -> None:
    emulator = Emulator(EmulatorConfig(listen=f"canopen://rest-{uuid.uuid4().hex}?interface=virtual"))
    try:
        with pytest.raises(ValueError, match=r"canopen: the emulator cannot be brought back to rest on this "
                                             r"transport \(only mavlink and zenoh\)"):
            emulator.rest()
    finally:
        emulator.close()
