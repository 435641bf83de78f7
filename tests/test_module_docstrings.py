"""Module docstrings stay short (issue 40, item 5): at most :data:`MAX_LINES` lines, what a reader of the code needs
(what the module does, units, signs, its interface, where the docs explain the rest); the stories live in docs/.

A module not cut yet is listed in :data:`NOT_YET_CUT` with its length today: it may not grow, and once it is cut
the test fails until its entry is removed, so the list only shrinks.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("analysis", "protocols", "drivers", "sim_table", "rig", "benchmarks")
MAX_LINES = 40
"""Longest module docstring [lines, its opening and closing quotes included]."""

NOT_YET_CUT: dict[str, int] = {
    "benchmarks/stream.py": 48,
    "rig/analyze/transform.py": 45,
    "rig/service/server.py": 47,
}
"""Module docstrings still over :data:`MAX_LINES` lines (path from the repository's root → lines today)."""


def docstring_lines(path: Path) -> int:
    """Lines of the module docstring of ``path`` (0: none)."""
    body = ast.parse(path.read_text(encoding="utf-8"), filename=str(path)).body
    first = body[0] if body else None
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        return (first.end_lineno or first.lineno) - first.lineno + 1
    return 0


def modules() -> list[str]:
    return sorted(str(path.relative_to(ROOT)) for folder in FOLDERS for path in (ROOT / folder).rglob("*.py"))


def test_every_module_docstring_is_at_most_40_lines() -> None:
    too_long = [f"{name}: {lines} lines" for name in modules() if name not in NOT_YET_CUT
                and (lines := docstring_lines(ROOT / name)) > MAX_LINES]
    assert not too_long, f"module docstrings over {MAX_LINES} lines (move the stories to docs/): {too_long}"


@pytest.mark.parametrize("name", sorted(NOT_YET_CUT))
def test_a_module_not_yet_cut_does_not_grow_and_leaves_the_list_once_cut(name: str) -> None:
    lines = docstring_lines(ROOT / name)
    assert lines <= NOT_YET_CUT[name], f"{name}: its docstring grew to {lines} lines (listed at {NOT_YET_CUT[name]})"
    assert lines > MAX_LINES, f"{name}: {lines} lines now: remove it from NOT_YET_CUT"
