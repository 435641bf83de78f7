"""The compiled kernels most tests reach, in groups that the xdist workers compile once between them.

From an empty numba cache the general model's fast engine takes 26–35 s of CPU to compile, the rest below about
20 s; each worker used to compile what its first tests needed, so both compiled the general engine at the same
time (measured: docs/notes/2026-12-06-test-suite.md). ``tests/conftest.py`` has each worker compile one group
under that group's lock, then take the other groups' locks in turn: it waits while another worker compiles one,
and then only loads it from the cache. Each group calls the public entry points as the tests do, so the
signatures compiled are the ones the tests use.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from analysis import Body
from analysis.simulate import simulate
from analysis.table.model import TableModel
from analysis.table.setpoint_screen import SetpointScreen
from sim_table.actuators import ActuatorSettings
from sim_table.dynamics import make_actuators
from sim_table.forward_kinematics import ForwardKinematics


def general_engine() -> None:
    """The general model's fast engine (``analysis.fast_general.simulate_general`` and what it calls)."""
    simulate(Body.from_p_alpha(2.0, 0.2), np.zeros(3), 0.01, model="general", solver="fast", theta0=0.1)


def rocking_engine_and_legs() -> None:
    """The rocking model's fast engine, the emulator's servo and lag legs, its forward kinematics and the setpoint
    screen (the last two compile in their constructors)."""
    ForwardKinematics(TableModel())
    SetpointScreen(TableModel())
    simulate(Body.from_p_alpha(2.0, 0.2), np.zeros(3), 0.01, model="rocking", solver="fast", theta0=0.1)
    for kind in ("servo", "lag"):
        legs = make_actuators(kind, TableModel(), 1e-3, ActuatorSettings(noise=0.0), payload=50.0)
        legs.step(np.zeros((5, 6)), np.zeros(5, bool))
        legs.measure(legs.lengths, legs.pose)


GROUPS: tuple[Callable[[], None], ...] = (general_engine, rocking_engine_and_legs)
"""Compiled in parallel, one per worker: the first is the largest alone."""
