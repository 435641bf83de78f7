"""Module docstrings stay short (issue 40, item 5): at most :data:`MAX_LINES` lines, what a reader of the code needs
(what the module does, units, signs, its interface, where the docs explain the rest); the stories live in docs/.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("analysis", "protocols", "drivers", "sim_table", "rig", "benchmarks")
MAX_LINES = 40
"""Longest module docstring [lines, its opening and closing quotes included]."""


def docstring_lines(path: Path) -> int:
    """Lines of the module docstring of ``path`` (0: none)."""
    body = ast.parse(path.read_text(encoding="utf-8"), filename=str(path)).body
    first = body[0] if body else None
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        return (first.end_lineno or first.lineno) - first.lineno + 1
    return 0


def test_docstring_lines_counts_the_quotes_and_nothing_but_the_docstring(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text('"""One.\n\nThree.\n"""\n\nX = 1\n')
    assert docstring_lines(module) == 4
    module.write_text('X = 1\n"""Not a docstring."""\n')
    assert docstring_lines(module) == 0


def test_every_module_docstring_is_at_most_40_lines() -> None:
    modules = sorted(path for folder in FOLDERS for path in (ROOT / folder).rglob("*.py"))
    assert len(modules) > 100, "the packages were not found"
    too_long = [f"{path.relative_to(ROOT)}: {lines} lines" for path in modules
                if (lines := docstring_lines(path)) > MAX_LINES]
    assert not too_long, f"module docstrings over {MAX_LINES} lines (move the stories to docs/): {too_long}"
