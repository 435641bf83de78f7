"""The documentation points inside the repository and agrees with the code: citations of docs/architecture.md name
its sections, every ``docs/….md`` path and markdown link resolves, the README is a user's guide that starts with
the two set-up commands, and the changelog's newest version is ``rig --version``'s (issue 40, items 1, 2, 5)."""

from __future__ import annotations

import re
from pathlib import Path

from typer.testing import CliRunner

from rig.cli import app

ROOT = Path(__file__).resolve().parents[1]


SKIPPED = re.compile(r"^(\.|build$|demo-output$|.*\.egg-info$)")
"""Directories that hold no source: hidden ones (.git, .venv), build outputs."""


def tracked(*patterns: str) -> list[Path]:
    """The repository's files matching the glob ``patterns``, outside `SKIPPED` directories."""
    return sorted(path for pattern in patterns for path in ROOT.rglob(pattern) if path.is_file()
                  and not any(SKIPPED.match(part) for part in path.relative_to(ROOT).parts[:-1]))


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8", errors="replace")


def test_citations_of_the_architecture_page_name_its_sections() -> None:
    sections = set(re.findall(r"^## (\d+)\. ", text(ROOT / "docs/architecture.md"), re.MULTILINE))
    old, unknown = [], []
    for path in tracked("*.py", "*.md"):
        name = str(path.relative_to(ROOT))
        body = text(path)
        if "ARCHITECTURE §" in body and name != "tests/test_docs.py":
            old.append(name)
        for cited in re.findall(r"architecture(?:\.md|\]\(architecture\.md\)) ((?:§\d+(?:, )?)+)", body):
            unknown += [f"{name}: §{n}" for n in re.findall(r"§(\d+)", cited) if n not in sections]
    assert old == [], "cite docs/architecture.md §N, not ARCHITECTURE §N"
    assert unknown == []


def test_every_docs_path_and_markdown_link_resolves() -> None:
    missing = []
    for path in tracked("*.py", "*.md", "*.toml", "Makefile"):
        body = text(path)
        missing += [f"{path.relative_to(ROOT)}: {ref}" for ref in re.findall(r"\bdocs/[\w./-]+\.md\b", body)
                    if not (ROOT / ref).is_file()]
        if path.suffix == ".md":
            for link in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", body):
                if "://" not in link and not (path.parent / link).exists():
                    missing.append(f"{path.relative_to(ROOT)}: ({link})")
    assert missing == []


def test_the_index_lists_every_page_and_notes_are_dated() -> None:
    index = text(ROOT / "docs/index.md")
    pages = [p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md") if p.name != "index.md"]
    assert [page for page in pages if f"]({page})" not in index] == []
    notes = [p.name for p in (ROOT / "docs/notes").glob("*.md")]
    assert notes and [n for n in notes if not re.fullmatch(r"\d{4}-\d{2}-\d{2}-[a-z0-9-]+\.md", n)] == []


def test_the_readme_is_a_guide_that_starts_with_the_two_commands() -> None:
    lines = text(ROOT / "README.md").splitlines()
    assert lines[2:6] == ["```sh",
                          "make demo    # set up .venv, start the emulated table and run examples/quick.toml on it "
                          "over MAVLink (~1 min)",
                          "make test    # set up .venv and run the tests (ruff, mypy, then the in-process tests "
                          "in parallel)",
                          "```"]
    assert len(lines) <= 300
    body = "\n".join(lines)
    assert "../shared" not in body
    assert "(docs/index.md)" in body and "(docs/architecture.md)" in body
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b(?!-)", body), "dated narrative belongs in docs/notes/"


def test_rig_version_is_the_changelog_s_newest_version() -> None:
    out = CliRunner().invoke(app, ["--version"])
    assert out.exit_code == 0, out.output
    newest = re.search(r"^## (\d+\.\d+\.\d+)\b", text(ROOT / "CHANGELOG.md"), re.MULTILINE)
    assert newest is not None, "CHANGELOG.md: no '## X.Y.Z' heading"
    assert out.output.strip() == f"rig {newest.group(1)}"
