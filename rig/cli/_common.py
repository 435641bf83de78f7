"""What every ``rig`` command shares: the consoles, errors and warnings, JSON output and exit codes.

``--json`` prints exactly one JSON object on stdout (:func:`emit_json`); errors go to stderr as one ``error: …``
line with exit code :data:`EXIT_USAGE` and no traceback (:func:`fail`).

Errors and warnings on stderr: one message, one line, greppable.

When stderr is not a terminal (``2>&1 | cat``, a log file, a test) nothing is wrapped at 80 columns: a
quoted header in an error stays on its line. On a terminal rich wraps to the window as usual. Messages are
printed as text, never as rich markup (a ``[1, 2]`` in a message stays as it is).
"""

from __future__ import annotations

import json
import signal
import sys
import warnings
from pathlib import Path
from typing import Any, NoReturn, TextIO

import typer
from rich.console import Console
from rich.text import Text


def handle_sigint(handler: Any) -> Any:
    """Install ``handler`` for SIGINT (only the main thread can: elsewhere nothing is installed); the previous one,
    to restore (None when none was installed)."""
    try:
        return signal.signal(signal.SIGINT, handler)
    except (ValueError, TypeError):
        return None


def stderr_console() -> Console:
    """A rich console on stderr that soft-wraps (does not break lines) unless stderr is a terminal."""
    return Console(stderr=True, soft_wrap=not sys.stderr.isatty())


def print_error(console: Console, label: str, message: str) -> None:
    """``label: message`` on ``console``, the label in bold red, the message as plain text."""
    console.print(Text.assemble((f"{label}:", "bold red"), " ", message))


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: TextIO | None = None, line: str | None = None) -> None:
    """``warning: …`` on stderr, one line (no source file and line of the Python code that warned)."""
    (file or sys.stderr).write(f"warning: {message}\n")


def plain_warnings() -> None:
    """Print warnings (e.g. `rig.records.RecordWarning`) as ``warning: …`` lines on stderr from now on."""
    warnings.showwarning = _show_warning


EXIT_STOPPED = 1
"""Exit code of a session that stopped early or was not started (``rig run``, ``rig demo``; resumable), or of a
``rig iterate`` whose run the table stopped."""
EXIT_USAGE = 2
"""Exit code of a usage error, bad input or a file that cannot be used (click's own for usage errors)."""
EXIT_REFUSED = 3
"""Exit code of ``rig prepare`` and ``rig iterate`` for a drive the table cannot play."""

console = Console(width=None if sys.stdout.isatty() else 160)
"""Where commands print for people (stdout; 160 columns when it is not a terminal)."""
err_console = stderr_console()
plain_warnings()


def fail(message: str, label: str = "error") -> NoReturn:
    """Print ``label: message`` on stderr (one line when stderr is not a terminal) and exit 2."""
    print_error(err_console, label, message)
    raise typer.Exit(code=EXIT_USAGE)


def fail_with(exc: BaseException) -> NoReturn:
    """:func:`fail` with an exception's message, under its ``label`` if it has one (``damaged: …`` for
    `rig.session.DamagedFileError`), else ``error: …``."""
    fail(str(exc), getattr(exc, "label", "error"))


def require_file(path: Path, what: str = "file") -> None:
    """Exit 2 (:func:`fail`) unless ``path`` is an existing file: checked before anything heavy is imported or
    anything is written, so that a mistyped name is said at once (issue 22)."""
    if not path.exists():
        fail(f"{path}: no such {what}")
    if not path.is_file():
        fail(f"{path}: not a {what} (a directory?)")


def emit_json(obj: dict, *, allow_nan: bool = True) -> None:
    """One JSON object on stdout (numpy scalars and arrays as numbers and lists); ``allow_nan=False`` refuses NaN
    and infinities instead of writing JavaScript's literals."""
    from rig.json_numpy import json_default

    sys.stdout.write(json.dumps(obj, default=json_default, allow_nan=allow_nan) + "\n")
