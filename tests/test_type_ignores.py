"""Every ``# type: ignore[code]`` in the packages mypy checks says why on its own line: ``# type: ignore[code]  #
reason`` (mypy itself refuses one without a code, and one no longer needed: ``[tool.mypy]`` in pyproject.toml).
Comments are read with ``tokenize``, so a docstring or a string that mentions the pragma is not one."""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("analysis", "protocols", "drivers", "sim_table", "rig")
"""The packages ``mypy`` checks (``files`` of ``[tool.mypy]``)."""

_PRAGMA = re.compile(r"#\s*type:\s*ignore\b(?:\[[^\]]*\])?(?P<after>.*)")
_REASON = re.compile(r"\s*#\s*\S")


def unexplained_ignores(source: str) -> list[int]:
    """The lines (from 1) of ``source`` whose comment holds a ``type: ignore`` not followed by ``# reason``."""
    lines = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type != tokenize.COMMENT:
            continue
        pragma = _PRAGMA.search(token.string)
        if pragma is not None and not _REASON.match(pragma["after"]):
            lines.append(token.start[0])
    return lines


def test_the_check_tells_a_reasoned_ignore_from_a_bare_one() -> None:
    source = ('x: int = "a"  # type: ignore[assignment]  # a str on purpose\n'
              'y: int = "b"  # type: ignore[assignment]\n'
              'z: int = "c"  # type: ignore\n'
              'w: int = "d"  # type: ignore[assignment] #\n'
              's = "# type: ignore[assignment]"\n')
    assert unexplained_ignores(source) == [2, 3, 4]


def test_every_type_ignore_in_the_packages_gives_its_reason() -> None:
    offenders = [f"{path.relative_to(ROOT)}:{line}"
                 for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py"))
                 for line in unexplained_ignores(path.read_text(encoding="utf-8"))]
    assert not offenders, ("a `# type: ignore[code]` without its reason on the same line (`# type: ignore[code]  "
                           "# why`): " + ", ".join(offenders))
