"""Errors and warnings of the ``rig`` command line on stderr: one message, one line, greppable.

When stderr is not a terminal (``2>&1 | cat``, a log file, a test) nothing is wrapped at 80 columns: a
quoted header in an error stays on its line. On a terminal rich wraps to the window as usual. Messages are
printed as text, never as rich markup (a ``[1, 2]`` in a message stays as it is).
"""

from __future__ import annotations

import sys
import warnings
from typing import Any, TextIO

from rich.console import Console
from rich.text import Text


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


def plain_warnings() -> Any:
    """Print warnings (e.g. `rig.records.RecordWarning`) as ``warning: …`` lines on stderr from now on."""
    warnings.showwarning = _show_warning
