"""The operator's day (issue 22): resume hints that work as printed, the table's bodies checked against the
sequence before any motion, errors before anything heavy is imported or written, and the CLI's manners
(``--version``, completion, ``--json``, ``iterate --speed max``, ``prepare -o``, ``emulate --help`` and counters).

Each hint the CLI prints here is run exactly as printed (``shlex.split``; ``rig`` is the command in this process,
``tests.helpers.cli.rig``), its operator prompts answered by their defaults (empty lines on stdin). As processes:
``rig run`` killed with ``kill -9``, what a fresh interpreter imports, and ``rig emulate`` stopped by SIGINT.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import Result

from drivers.controller import open_table
from rig.cli import app
from rig.emulator import EmulatorProcess
from rig.orchestrator.bodies import mismatch
from rig.sequence import Sequence, load_sequence
from rig.session import read_session
from tests.helpers.cli import rig
from tests.helpers.processes import HEAVY, start_tiny
from tests.helpers.sequences import TINY
from tests.helpers.tables import SharedTable

ROOT = Path(__file__).resolve().parents[2]
RIG = [sys.executable, "-m", "rig.cli"]
QUICK = ROOT / "examples" / "quick.toml"


def run_hint(hint: str, cwd: Path, stdin: str = "") -> Result:
    """The printed command ``rig …`` run as printed."""
    words = shlex.split(hint)
    assert words[0] == "rig", hint
    return rig(*words[1:], cwd=cwd, stdin=stdin)


def options_of(*command: str) -> set[str]:
    """Every option name of ``rig COMMAND …``."""
    group = typer.main.get_command(app)
    for name in command:
        group = group.commands[name]  # type: ignore[attr-defined]
    return {opt for param in group.params for opt in (*param.opts, *param.secondary_opts)}



# ----- item 1: resume hints that work as printed -----------------------------------------------------------------


@pytest.mark.integration
def test_the_printed_resume_hint_continues_on_the_same_emulated_table(tmp_path: Path) -> None:
    """The operator declines to place the bodies: the session stops early and names the command that continues
    it; that command, as printed (no --emulate, no --speed), plays the rest on the emulator with the sequence's
    bodies at the session's speed (max), and completes the session."""
    (tmp_path / "tiny.toml").write_text(TINY)
    stopped = rig("run", "tiny.toml", "--emulate", "--speed", "max", "-o", "s.h5", cwd=tmp_path, stdin="n\n")
    assert stopped.exit_code == 1, stopped.stderr + stopped.stdout
    hint = re.search(r"continue it with (rig run .*)$", stopped.stdout, re.MULTILINE)
    assert hint is not None, stopped.stdout
    assert read_session(tmp_path / "s.h5")["runs"] == []
    done = run_hint(hint.group(1), tmp_path, stdin="\n" * 40)  # every prompt answered by its default
    assert done.exit_code == 0, done.stderr + done.stdout
    runs = read_session(tmp_path / "s.h5")["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(0, "completed"), (1, "completed")]
    counters = json.loads((tmp_path / "s.emulator.json").read_text())
    assert counters["speed"] == "max" and counters["streams_completed"] == 2  # the session's emulator, again


@pytest.mark.integration
@pytest.mark.slow  # the crashed session resumes at the speed it ran at: 1x, about 20 s
def test_after_a_crash_the_recover_hint_and_then_the_resume_hint_work_as_printed(tmp_path: Path) -> None:
    """``kill -9`` of ``rig run --emulate`` mid-record; ``rig sessions recover`` names the command that continues
    the session, and that command (``rig run --resume s.h5``: no table named) finishes it on the emulator."""
    proc, session, _ = start_tiny(tmp_path)
    try:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # the emulator it started
    recovered = rig("sessions", "recover", str(session), cwd=tmp_path)
    assert recovered.exit_code == 0, recovered.stderr
    hint = re.search(r"continue the session with (rig run .*)$", recovered.stdout, re.MULTILINE)
    assert hint is not None, recovered.stdout
    done = run_hint(hint.group(1), tmp_path, stdin="\n" * 40)  # as printed: on the session's emulator, at 1x
    assert done.exit_code == 0, done.stderr + done.stdout
    runs = read_session(session)["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(0, "interrupted"), (0, "completed"), (1, "completed")]


@pytest.mark.integration
def test_resume_on_a_real_table_url_reuses_it_and_names_the_key(tmp_path: Path, tiny: Sequence,
                                                                body_table: Callable[..., SharedTable]) -> None:
    """A session on a table URL stores it; when it stops early the hint (with its key file) reaches that table (the
    session's emulator with the sequence's bodies, ``body_table``)."""
    table = body_table(tiny)
    key_file = table.key_file
    stopped = rig("run", "tiny.toml", "--table", table.url, "--key-file", str(key_file), "-o", "s.h5",
                  cwd=tmp_path, stdin="n\n")
    assert stopped.exit_code == 1, stopped.stderr + stopped.stdout
    hint = re.search(r"continue it with (rig run .*)$", stopped.stdout, re.MULTILINE)
    assert hint is not None and f"--key-file {key_file}" in hint.group(1)
    assert read_session(tmp_path / "s.h5")["attrs"]["table"] == json.dumps({"url": table.url})
    done = run_hint(hint.group(1), tmp_path, stdin="\n" * 40)
    assert done.exit_code == 0, done.stderr + done.stdout  # the hint reached the table and played on it
    runs = read_session(tmp_path / "s.h5")["runs"]
    assert {r["attrs"]["table_url"] for r in runs} == {table.url}
    assert [r["status"] for r in runs] == ["completed", "completed"]


def test_the_services_no_table_message_names_flags_that_exist(tmp_path: Path) -> None:
    from rig.service.session import ServiceSession, StartRequest

    (tmp_path / "tiny.toml").write_text(TINY)
    session = ServiceSession(StartRequest(sequence=tmp_path / "tiny.toml"), sessions_dir=tmp_path, key_file=None,
                             on_update=lambda: None)
    session.start()
    assert session.wait_started(60)
    assert session.error is not None and "emulate: true" not in session.error
    named = set(re.findall(r"--[a-z][a-z-]*", session.error))
    assert named and named <= options_of("run"), session.error
    assert not list(tmp_path.glob("*.h5"))


# ----- item 2: the bodies on the table checked against the sequence -------------------------------------------


@pytest.mark.integration
def test_a_table_holding_other_bodies_is_refused_before_any_motion(tmp_path: Path, key_file: Path) -> None:
    """An emulator holding one 0.10 x 0.50 body, the quick sequence's two: refused with both lists, exit 2, no
    session file, the table never armed; the MAVLink report carries the specimens' sizes and places."""
    with EmulatorProcess.start("mavlink://127.0.0.1:0", "--body", "0.1x0.5@0.05,0.02;depth=0.3", "--speed", "max",
                               key_file=key_file) as emulator:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            (body,) = table.bodies()
        np.testing.assert_allclose([body.b, body.h, body.depth, body.x, body.y], [0.1, 0.5, 0.3, 0.05, 0.02],
                                   rtol=1e-6)
        done = rig("run", str(QUICK), "--table", emulator.url, "--key-file", str(key_file), "--yes", "-o", "s.h5",
                   cwd=tmp_path)
        counters = emulator.stop()
    assert done.exit_code == 2, done.stderr + done.stdout
    assert "T5-4 0.039x0.200 m" in done.stderr and "T5-5 0.049x0.200 m" in done.stderr  # the sequence's
    assert "body 0 0.100x0.500 m (depth 0.300 m) at (0.050, 0.020) m" in done.stderr  # the table's
    assert "the sequence has 2 bodies, the table 1" in done.stderr
    assert not (tmp_path / "s.h5").exists()
    assert counters["commands_accepted"] == 0 and counters["streams_started"] == 0


@pytest.mark.integration
def test_zenoh_reports_the_emulators_bodies(key_file: Path) -> None:
    emulator = EmulatorProcess.start("zenoh://127.0.0.1:0/table", "--body", "0.1x0.5@0.05,0.3;depth=0.3", "--body",
                                     "0.2x0.6@0,-0.3", "--speed", "max", key_file=key_file)
    with emulator, open_table(emulator.url, key_file=str(key_file)) as table:
        bodies = table.bodies()
    assert bodies is not None
    np.testing.assert_array_equal([(b.body_id, b.b, b.h, b.depth, b.x, b.y) for b in bodies],
                                  [(0, 0.1, 0.5, 0.3, 0.05, 0.3), (1, 0.2, 0.6, 0.4, 0.0, -0.3)])  # depth 2b


def test_what_is_compared(tmp_path: Path) -> None:
    """Sizes and places within 1 mm; a detector channel without a size (a real table's): only the count."""
    from drivers.bodies import TableBody

    (tmp_path / "tiny.toml").write_text(TINY)
    (body,) = load_sequence(tmp_path / "tiny.toml").bodies
    same = TableBody(0, body.body.b, body.body.h, body.depth, body.x, body.y)
    assert mismatch([body], [same]) is None
    assert mismatch([body], [TableBody(0, body.body.b + 0.0005, body.body.h, body.depth, body.x, body.y)]) is None
    moved = mismatch([body], [TableBody(0, body.body.b, body.body.h, body.depth, body.x + 0.1, body.y)])
    assert moved is not None and "x 0.000 m against 0.100 m" in moved
    taller = mismatch([body], [TableBody(0, body.body.b, 2 * body.body.h, body.depth, body.x, body.y)])
    assert taller is not None and "h " in taller
    assert mismatch([body], [TableBody(0, 0.0, 0.0, 0.0, 0.0, 0.0)]) is None  # a channel: the count matches
    assert mismatch([body], []) == "the sequence has 1 bodies, the table 0"


# ----- item 3: errors before anything heavy or written -----------------------------------------------------------

_PROBE = r"""
import json, sys
from typer.testing import CliRunner
from rig.cli import app
result = CliRunner().invoke(app, sys.argv[2:])
print(json.dumps({"exit": result.exit_code, "output": result.output,
                  "loaded": sorted(m for m in json.loads(sys.argv[1]) if m in sys.modules)}))
"""


@pytest.mark.integration
@pytest.mark.parametrize("args", [["report", "nope.h5"], ["sessions", "show", "nope.h5"],
                                  ["analyze", "nope.h5"], ["run", "--resume", "nope.h5", "--yes"],
                                  ["run", "nope.toml", "--emulate"]])
def test_a_missing_file_is_said_before_anything_heavy_is_imported(tmp_path: Path, args: list[str]) -> None:
    out = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(HEAVY), *args], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300, check=True).stdout
    seen = json.loads(out)
    assert seen["exit"] == 2 and "nope" in seen["output"] and "no such" in seen["output"]
    assert seen["loaded"] == [], seen["loaded"]


@pytest.mark.integration  # opens a socket
def test_a_table_that_does_not_answer_leaves_no_session_file(tmp_path: Path, key_file: Path) -> None:
    (tmp_path / "tiny.toml").write_text(TINY)
    done = rig("run", "tiny.toml", "--table", "mavlink://127.0.0.1:9", "--key-file", str(key_file),
                          "--yes", "-o", "s.h5", cwd=tmp_path)
    assert done.exit_code == 2, done.stderr + done.stdout
    assert "mavlink://127.0.0.1:9 did not answer" in done.stderr
    assert not list(tmp_path.glob("*.h5"))


# ----- item 6: CLI manners ----------------------------------------------------------------------------------------


def test_version_and_shell_completion(monkeypatch: pytest.MonkeyPatch) -> None:
    from rig import __version__

    assert rig("--version", cwd=ROOT).stdout == f"rig {__version__}\n"
    assert {"--install-completion", "--show-completion", "--version"} <= options_of()
    # the shell named, not detected from the parent processes; read as the command is built, before CliRunner's env
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    script = rig("--show-completion", "bash", cwd=ROOT)
    assert script.exit_code == 0 and "complete" in script.stdout and "rig" in script.stdout


@pytest.mark.integration
def test_json_options_print_one_object(tmp_path: Path) -> None:
    (tmp_path / "tiny.toml").write_text(TINY)
    for command in (("run",), ("demo",), ("sessions", "list"), ("sessions", "show")):
        assert "--json" in options_of(*command), command
    done = rig("run", "tiny.toml", "--emulate", "--speed", "max", "--yes", "--json", "-o", "s.h5", cwd=tmp_path)
    run = json.loads(done.stdout)  # exactly one object (json.loads refuses anything after it), whatever the outcome
    assert done.exit_code == (0 if run["complete"] else 1), done.stderr
    assert run["runs_total"] == 2 and run["session"].endswith("s.h5") and "session file: s.h5" in done.stderr
    assert run["resume"] == (None if run["complete"] else "rig run --resume s.h5 --yes")
    if run["complete"]:
        assert run["runs_done"] == 2 and run["state"] == "done"
    shown = json.loads(rig("sessions", "show", "s.h5", "--json", cwd=tmp_path).stdout)
    assert [r["status"] for r in shown["runs"]] == [r["status"] for r in read_session(tmp_path / "s.h5")["runs"]]
    assert shown["table"] == {"emulate": True, "speed": "max"} and shown["sequence"] == "tiny"
    listed = json.loads(rig("sessions", "list", ".", "--json", cwd=tmp_path).stdout)
    assert [Path(s["path"]).name for s in listed["sessions"]] == ["s.h5"]


def test_iterate_takes_speed_max() -> None:
    from rig.cli.iterate import _Table

    assert _Table(None, True, None, None, "lag", [], math.inf).flags[-2:] == ["--speed", "max"]
    refused = rig("iterate", "fema:NORTHR/MUL009", "--emulate", "--speed", "fast", cwd=ROOT)
    assert refused.exit_code == 2 and "expected a factor > 0 or max" in refused.stderr


def test_prepare_saves_a_drive_a_sequence_plays_and_its_table_shows_units(tmp_path: Path) -> None:
    done = rig("prepare", "fema-farfield:KOBE/NIS000", "--angle", "4", "-o", "kobe.drive.h5", cwd=tmp_path)
    assert done.exit_code == 0, done.stderr
    for header in ("displacement [m]", "velocity [m/s]", "acceleration [g]"):
        assert header in done.stdout, done.stdout
    assert "drive file: " in done.stdout
    (tmp_path / "seq.toml").write_text(TINY.replace(
        '    { record = "fema-farfield:KOBE/NIS000", window_s = [5.0, 8.0] },\n', "").replace(
        '{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 3.5] }',
        '{ record = "fema-farfield:KOBE/NIS000", drive = "kobe.drive.h5" }').replace("[0]", "[4]"))
    sequence = load_sequence(tmp_path / "seq.toml")
    (planned,) = sequence.plan()
    played = sequence.prepare(planned)
    fresh = json.loads(rig("prepare", "fema-farfield:KOBE/NIS000", "--angle", "4", "--json",
                                      cwd=tmp_path).stdout)
    assert played.scale_factor == pytest.approx(fresh["scale_factor"]) and len(played.t) == fresh["samples"]
    again = rig("prepare", "fema-farfield:KOBE/NIS000", "--angle", "4", "-o", "kobe.drive.h5",
                           cwd=tmp_path)
    assert again.exit_code == 2 and "never overwritten" in again.stderr


@pytest.mark.integration
def test_emulate_help_and_counters_table(tmp_path: Path, key_file: Path) -> None:
    help_text = rig("emulate", "--help", cwd=ROOT).stdout
    assert help_text.startswith("Usage: rig emulate [OPTIONS]")
    for option in ("--listen URL", "--body", "--speed FACTOR|max", "--json", "--counters FILE"):
        assert option in help_text, option
    assert "usage: python -m sim_table" not in help_text  # argparse's own style is gone
    proc = subprocess.Popen([*RIG, "emulate", "--listen", "mavlink://127.0.0.1:0", "--speed", "max", "--key-file",
                             str(key_file)], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    for line in proc.stderr:
        if "listening on" in line:
            break
    proc.send_signal(2)  # SIGINT, as Ctrl-C: passed on to the emulator, which stops and hands over its counters
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0
    assert "{" not in out and "the emulator's counters" in out
    assert re.search(r"underruns\s+0", out) and re.search(r"link\.packets_sent\s+\d+", out)
