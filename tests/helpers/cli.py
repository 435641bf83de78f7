"""``rig …`` in this process, through typer's ``CliRunner``: the same app, arguments, exit code, stdout, stderr and
files as the command, without a process (for tests where the process is not what is checked: no signal, kill,
process lifetime, real time, or what a fresh interpreter imports)."""

from __future__ import annotations

import contextlib
from pathlib import Path

from typer.testing import CliRunner, Result

from rig.cli import app

COLUMNS = "160"
"""The terminal width the output is laid out for (the subprocess tests' ``COLUMNS``)."""


def rig(*args: str, cwd: Path | None = None, stdin: str | None = None,
        env: dict[str, str] | None = None) -> Result:
    """Run ``rig ARGS…`` in ``cwd`` (default: where the test runs) with ``stdin`` as its input; the result's
    ``exit_code``, ``stdout`` and ``stderr`` are the command's (an exception it did not handle is re-raised, with
    its traceback, as the test's failure)."""
    runner = CliRunner()
    with contextlib.chdir(cwd) if cwd is not None else contextlib.nullcontext():
        result = runner.invoke(app, list(args), input=stdin, env={"COLUMNS": COLUMNS, **(env or {})},
                               prog_name="rig", catch_exceptions=False)
    return result
