"""``rig run … --console HOST:PORT`` without a separate service: the console serves the run's state from the
in-process service's telemetry while the emulated table plays the tiny sequence, and the run ends as ``rig run
--service`` does (exit code 0 when every run is done) — at once with ``--console-linger 0``, else once the operator
closes the console that outlived the run. ``rig run`` in this process, except where a signal is what is checked."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from tests.helpers.cli import rig
from tests.helpers.processes import free_port
from tests.helpers.sequences import TINY

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)


def state(url: str) -> dict[str, Any] | None:
    try:
        with urllib.request.urlopen(f"{url}api/state", timeout=5) as response:
            return json.loads(response.read())
    except (urllib.error.URLError, ConnectionError, TimeoutError):
        return None


@pytest.mark.slow  # a whole session at 1x through an in-process service and the console
def test_rig_run_with_a_console(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``rig`` in this process (``tests.helpers.cli.rig``), the console watched from a thread as the run plays."""
    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY)
    url = f"http://127.0.0.1:{free_port()}/"
    monkeypatch.delenv("SHAKETABLE_MAVLINK_KEY", raising=False)
    seen: set[str] = set()
    frames = [0]
    over = threading.Event()

    def watch() -> None:
        while not over.is_set():
            current = state(url)
            if current is not None and current["status"] is not None:
                seen.add(current["status"]["state"])
                frames[0] = max(frames[0], len(current["accel"]["t"]))
            over.wait(0.2)

    watcher = threading.Thread(target=watch, name="console watcher", daemon=True)
    watcher.start()
    try:
        run = rig("run", str(sequence), "--emulate", "--yes", "--console", url.removeprefix("http://").rstrip("/"),
                  "--console-linger", "0", cwd=tmp_path)
    finally:
        over.set()
        watcher.join(10)
    output = run.stdout + run.stderr
    assert "operator console: " + url in output and "operator token " in output
    assert "running" in seen, seen  # the page's server followed the session
    assert frames[0] > 0  # and received its live data
    sessions = list(tmp_path.glob("session-*-tiny.h5"))
    assert len(sessions) == 1, output  # the session file where rig run writes it
    assert run.exit_code in (0, 1), output  # 1: the emulator faulted under load (the message says so)
    if run.exit_code == 0:
        assert "done: 2 of 2 runs done" in output


@pytest.mark.slow  # a whole session (virtual time) through an in-process service and the console
def test_the_console_outlives_the_run_until_ctrl_c(tmp_path: Path) -> None:
    """After the session the console still answers: the final state, the report (sandboxed); Ctrl-C (SIGINT to the
    process group, as a terminal sends it) closes it and ``rig run`` exits with the session's code — also when
    ``rig run`` was started with SIGINT ignored, as a script's background job is (Python then raises no
    KeyboardInterrupt: the lingering console sat through the SIGINT until killed)."""
    import signal

    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY)
    url = f"http://127.0.0.1:{free_port()}/"
    env = {k: v for k, v in os.environ.items() if k != "SHAKETABLE_MAVLINK_KEY"}
    log = tmp_path / "run.log"
    with log.open("w") as out:
        run = subprocess.Popen([str(Path(sys.executable).with_name("rig")), "run", str(sequence), "--emulate",
                                "--yes", "--speed", "max", "--console", url.removeprefix("http://").rstrip("/")],
                               cwd=tmp_path, env=env, stdout=out, stderr=subprocess.STDOUT, text=True,
                               start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))  # a background job's
    try:
        deadline = time.monotonic() + 180
        while "the console stays up" not in log.read_text():
            assert run.poll() is None, log.read_text()
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.2)
        time.sleep(2.0)  # the session is over: the page still answers, with its final state
        final = state(url)
        assert final is not None and final["status"]["state"] == "done" and not final["status"]["active"]
        assert final["status"]["progress"]["outcomes"] == {"0": "completed", "1": "completed"}
        with urllib.request.urlopen(f"{url}report", timeout=120) as response:
            assert response.status == 200 and response.headers["Content-Security-Policy"].startswith("sandbox;")
            assert b"<html" in response.read(2000).lower()
        assert run.poll() is None  # still up
        os.killpg(run.pid, signal.SIGINT)  # the operator's Ctrl-C
        try:
            code = run.wait(60)
        except subprocess.TimeoutExpired:
            code = None
        assert code == 0, log.read_text()
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    output = log.read_text()
    assert "console closed" in output and "done: 2 of 2 runs done" in output
    assert state(url) is None  # closed
