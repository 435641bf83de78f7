"""Shared fixtures (kept small on purpose), and the check that keeps the ``integration`` mark true.

Tests are grouped by the layer they check: ``tests/analysis`` (the models, the table's machine model, studies),
``tests/emulator`` (``sim_table``), ``tests/transports`` (``protocols`` and ``drivers`` against the emulated table),
``tests/rig`` (sessions, records, sequences, orchestrator, service, console, report, CLI); ``tests/test_layers.py``
checks the imports of the whole project. A test that starts a process or opens a network socket is marked
``integration`` (``pytestmark`` in its file): :func:`_integration_mark_is_true` makes any other test fail when it
does either, so ``-m "not integration"`` is a suite of in-process unit tests.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer

from analysis import Body
from protocols.signing_key import write_signing_key
from rig.cli.records import register as register_records
from rig.emulator import EmulatorProcess

# the helpers' asserts say what they compared, as a test's own do (before any test module imports them)
pytest.register_assert_rewrite("tests.helpers")


@pytest.fixture
def v_body() -> Body:
    """The VALIDATION.md block: p = 2 rad/s, α = 0.2 rad (b ≈ 0.729 m, h ≈ 3.61 m)."""
    return Body.from_p_alpha(2.0, 0.2)


@pytest.fixture(scope="module")
def key_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A signing key for the rig and the emulated table, one per test module (random, mode 0600)."""
    path = tmp_path_factory.mktemp("key") / "rig.key"
    write_signing_key(path)
    return path


@pytest.fixture(scope="session")
def shared_key_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The signing key of the emulated tables the session shares (``tests/helpers/tables.py``; random, mode 0600)."""
    path = tmp_path_factory.mktemp("shared-key") / "rig.key"
    write_signing_key(path)
    return path


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    """A Typer app with only the ``records`` command group mounted (what `rig records …` runs)."""
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test root."""

    register_records(app)
    return app


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Under xdist, the workers compile the kernels of ``tests/helpers/kernels.py`` between them before their first
    test: worker k starts with group k, then takes each other group's lock in turn (waiting while the worker that
    holds it compiles), so each group is compiled once and loaded from numba's cache by the others. One process
    alone compiles each kernel at its first use, as before."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers < 2:
        return
    from analysis.compiled_index import exclusive
    from tests.helpers.kernels import GROUPS

    first = int(os.environ["PYTEST_XDIST_WORKER"].removeprefix("gw"))
    shared = tmp_path_factory.getbasetemp().parent  # the run's directory, above each worker's popen-gw<k>
    for k in range(len(GROUPS)):
        group = (first + k) % len(GROUPS)
        with exclusive(shared / f"kernels-{group}.lock"):
            GROUPS[group]()


_emulator_starts = [0]


@pytest.fixture(scope="session", autouse=True)
def _count_emulator_starts() -> Iterator[None]:
    """Count the emulator processes the tests start (``EmulatorProcess.start`` in this process; those ``rig run
    --emulate`` starts in a process of its own are not seen), named in the run's summary: a shared table
    (``tests/helpers/tables.py``) is one start for all the tests it serves."""
    start = EmulatorProcess.start.__func__

    def counted(cls: type[EmulatorProcess], *args: Any, **kwargs: Any) -> EmulatorProcess:
        _emulator_starts[0] += 1
        return start(cls, *args, **kwargs)  # type: ignore[no-any-return]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(EmulatorProcess, "start", classmethod(counted))
        yield


def _importing() -> bool:
    """Whether a module is being imported up the call stack: what a library does as it is first imported (h5py asks
    the platform module, which runs ``uname -p``) is not the test's doing, and happens in whichever test comes first."""
    frame = sys._getframe(2)
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


@pytest.fixture(autouse=True)
def _integration_mark_is_true(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Fail a test not marked ``integration`` that starts a process (``subprocess.Popen``, which ``subprocess.run``
    and ``multiprocessing``'s spawn use) or creates an IPv4/IPv6 socket (local socket pairs, e.g. asyncio's, are
    allowed), except while a library is being imported (:func:`_importing`). Sockets opened inside compiled
    extensions (zenoh) are not seen; their tests are marked anyway."""
    if request.node.get_closest_marker("integration") is not None:
        yield
        return
    test = request.node.nodeid
    popen_init, socket_init = subprocess.Popen.__init__, socket.socket.__init__

    def popen(self: subprocess.Popen, *args: object, **kwargs: object) -> None:
        if not _importing():
            raise AssertionError(f"{test} starts a process but is not marked integration")
        popen_init(self, *args, **kwargs)  # type: ignore[arg-type]

    def new_socket(self: socket.socket, family: int = -1, *args: object, **kwargs: object) -> None:
        if family in (socket.AF_INET, socket.AF_INET6, -1) and not _importing():
            raise AssertionError(f"{test} opens a network socket but is not marked integration")
        socket_init(self, family, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(subprocess.Popen, "__init__", popen)
    monkeypatch.setattr(socket.socket, "__init__", new_socket)
    yield


# --------------------------------------------------------------------------------------------------
# the fast tier's time budget: a test not marked integration or slow is meant to take seconds; one that takes longer
# than FAST_BUDGET_S is named at the end of the run (so it shows up the day it is written), and pytest-timeout
# (`make test`: --timeout) fails one that hangs, with its stack

FAST_BUDGET_S = 20.0
_over_budget: list[tuple[float, str]] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.when != "call" or report.duration <= FAST_BUDGET_S:
        return
    if {"integration", "slow"} & set(report.keywords):
        return
    _over_budget.append((report.duration, report.nodeid))


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _emulator_starts[0]:
        terminalreporter.write_line(f"emulator processes started by the tests (EmulatorProcess.start): "
                                    f"{_emulator_starts[0]}")
    if not _over_budget:
        return
    terminalreporter.section(f"fast-tier tests over their {FAST_BUDGET_S:.0f} s budget: make them cheaper or mark slow")
    for duration, nodeid in sorted(_over_budget, reverse=True):
        terminalreporter.write_line(f"{duration:7.1f} s  {nodeid}")
