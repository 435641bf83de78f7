"""Ctrl-C stops a tool that is opening a session file (issue 42, item 2): ``rig sessions show`` on a damaged file
that a live writer holds (so the reader keeps retrying: the writer may be mid-update) ends at SIGINT, with no
traceback. Before the fix it sat inside HDF5 (a SWMR reader's retries of a bad block never end) and SIGINT did
nothing.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rig.session import SessionLog
from rig.session.locks import open_locked

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

REPO = Path(__file__).resolve().parents[2]


def _asleep_with_hdf5_loaded(pid: int) -> bool:
    """Whether process ``pid`` has loaded HDF5 (h5py imported: it is opening the file or about to) and is asleep."""
    try:
        with open(f"/proc/{pid}/maps") as maps:
            if "libhdf5" not in maps.read():
                return False
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] == "S"
    except (FileNotFoundError, ProcessLookupError):
        return False


def _wait_until_it_waits(tool: subprocess.Popen, asleep_s: float = 0.03) -> None:
    """Until ``tool`` has slept ``asleep_s`` on end with HDF5 loaded: waiting between a reader's tries, or (before
    the fix) inside HDF5's retries of a bad block. A process that imports or computes is running, not asleep."""
    since = None
    while tool.poll() is None:
        if not _asleep_with_hdf5_loaded(tool.pid):
            since = None
        elif since is None:
            since = time.monotonic()
        elif time.monotonic() - since >= asleep_s:
            return
        time.sleep(0.001)


def test_sigint_stops_a_tool_while_it_opens_a_damaged_file(tmp_path: Path) -> None:
    good = tmp_path / "good.h5"
    log = SessionLog.create(good, {"table": {}}, {"name": "interrupt"}, "0.1.0+test")
    run = log.begin_run(0, record="suite:a", scale_factor=0.5, angle_deg=5.0, commanded=np.zeros((10, 7)),
                        bodies=[{"body_id": 1, "b": 0.1, "h": 0.5, "depth": 0.1, "mass": 4.0, "x": 0.0, "y": 0.0}],
                        sensors=["plate"])
    run.end("completed")
    log.close()
    path = tmp_path / "session.h5"
    path.write_bytes(good.read_bytes()[:802])
    fd = open_locked(path)  # a live writer holds it: the reader retries instead of answering at once
    try:
        tool = subprocess.Popen([sys.executable, "-m", "rig.cli", "sessions", "show", str(path)], cwd=REPO,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            _wait_until_it_waits(tool)
            assert tool.poll() is None, f"ended before it was interrupted: {tool.communicate()}"
            tool.send_signal(signal.SIGINT)
            _out, err = tool.communicate(timeout=10)
        finally:
            if tool.poll() is None:
                tool.kill()
                tool.communicate()
    finally:
        os.close(fd)
    assert tool.returncode != 0
    assert "Traceback" not in err, err
