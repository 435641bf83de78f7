"""Processes in tests: free ports, ``rig`` and its children, the heavy imports a light command must not pay."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from rig.session import read_session
from tests.helpers.sequences import TINY

ROOT = Path(__file__).resolve().parents[2]
RIG = [sys.executable, "-m", "rig.cli"]
"""``rig`` as a process of this interpreter."""


def start_tiny(tmp_path: Path, stdin: int | None = None) -> tuple[subprocess.Popen[bytes], Path, float]:
    """``rig run`` of the tiny sequence on the emulator, in its own process group; returned once it is 1 s into
    the first record, with the time [s] of the last sample seen then."""
    (tmp_path / "tiny.toml").write_text(TINY)
    session = tmp_path / "s.h5"
    proc = subprocess.Popen([*RIG, "run", "tiny.toml", "--emulate", "--yes", "-o", str(session)], cwd=tmp_path,
                            stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    seen, deadline = 0.0, time.monotonic() + 120
    while seen < 1.0:
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.2)
        if session.exists():
            runs = read_session(session)["runs"]
            if runs and len(runs[0]["accel"].get("0", [])):
                seen = runs[0]["accel"]["0"][-1, 0]
    return proc, session, seen


def running(pid: int, module: bytes) -> bool:
    """Whether process ``pid`` is ``python -m module`` still running (Linux /proc: gone, or a zombie with no command
    line, is not)."""
    try:
        return module in Path(f"/proc/{pid}/cmdline").read_bytes()
    except (FileNotFoundError, ProcessLookupError):
        return False


def child_of(proc: subprocess.Popen[Any], module: bytes) -> int:
    """The pid of the one ``python -m module`` that ``proc`` started (among its children; Linux /proc)."""
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
    found = [int(child) for child in children if running(int(child), module)]
    assert len(found) == 1, f"{len(found)} {module.decode()} among the children {children} of {proc.pid}"
    return found[0]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def serve_command() -> list[str]:
    return [str(Path(sys.executable).with_name("rig")), "serve"]


#: Modules whose import takes a noticeable part of a second (or pulls in such modules).
HEAVY = ("numpy", "scipy", "numba", "matplotlib", "h5py", "mujoco", "dask", "distributed", "zenoh", "pymavlink",
         "canopen", "can", "hypothesis", "rig.records", "rig.session", "rig.orchestrator", "rig.report",
         "rig.analyze", "rig.drive", "rig.service", "analysis.simulate", "analysis.study", "analysis.design",
         "analysis.table.model")
