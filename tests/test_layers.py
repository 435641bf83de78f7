"""The layers of docs/architecture.md, read from the imports as they are (``ast``, nothing imported).

A rule broken today is marked ``xfail(strict=True)`` with the import that breaks it: the test documents the
debt and fails (XPASS) once it is paid — then remove the mark and update docs/architecture.md.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("analysis", "protocols", "drivers", "sim_table", "rig")

ALLOWED = {
    "analysis": set(),
    "protocols": set(),
    "drivers": {"analysis", "protocols"},
    "sim_table": {"analysis", "protocols"},
    "rig": {"analysis", "protocols", "drivers"},
}
"""Which of our packages each package may import (docs/architecture.md, Layers)."""

RIG_LAYERS = {
    "cli": 4, "console": 4,
    "service": 3,
    "orchestrator": 2, "report": 2, "emulator": 2, "compensation": 2,
    "sequence": 1, "analyze": 1, "study_file": 1, "study_summary": 1,
    "session": 0, "certs": 0, "records": 0, "drive": 0, "json_numpy": 0,
}
"""Inside ``rig``: a unit (a subpackage such as ``cli``, or a top-level module) may
import units of its own layer or below (docs/architecture.md, Inside rig). ``rig`` itself holds only
``__version__``."""


def _type_checking_only(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(tree: ast.AST) -> Iterator[str]:
    """Absolute module names imported anywhere (functions included), except under ``if TYPE_CHECKING:``."""
    for node in ast.iter_child_nodes(tree):
        if _type_checking_only(node):
            continue
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module
            yield from (f"{node.module}.{alias.name}" for alias in node.names)
        yield from _imports(node)


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def _graph() -> dict[str, set[str]]:
    """Our modules and the modules of ours each imports (``from pkg import name``: the submodule when it is one)."""
    files = {_module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        targets = set()
        for imported in _imports(ast.parse(path.read_text(), str(path))):
            if imported in files:
                targets.add(imported)
        graph[name] = targets - {name}
    # `from pkg import sub` adds both "pkg" and "pkg.sub"; keep the submodule only
    for name, targets in graph.items():
        graph[name] = {t for t in targets if not any(o.startswith(t + ".") for o in targets)}
    return graph


def _rig_unit(module: str) -> str:
    part = module.split(".")[1] if "." in module else ""
    return part


def _breaches(package: str) -> list[str]:
    return sorted(f"{module} imports {target}" for module, targets in _graph().items()
                  if module.split(".")[0] == package for target in targets
                  if target.split(".")[0] not in ALLOWED[package] | {package})


def _import_circles() -> list[list[str]]:
    """The circles among the layers' units (top-level packages; in ``rig``, its units), one per pair of units."""

    def unit(module: str) -> str:
        return f"rig.{_rig_unit(module)}" if module.startswith("rig.") else module.split(".")[0]

    edges: dict[str, set[str]] = {}
    for module, targets in _graph().items():
        for target in targets:
            if unit(target) != unit(module) and target != "rig":
                edges.setdefault(unit(module), set()).add(unit(target))
    circles = []
    for start in sorted(edges):
        stack = [(start, [start])]
        seen = set()
        while stack:
            node, path = stack.pop()
            for nxt in sorted(edges.get(node, ())):
                if nxt == start and min(path) == start:
                    circles.append([*path, start])
                elif nxt not in seen and nxt not in path:
                    seen.add(nxt)
                    stack.append((nxt, [*path, nxt]))
    return circles


def test_the_graph_sees_the_imports() -> None:
    graph = _graph()
    assert "analysis.general_stages" in graph["analysis.fast_general"]
    assert "drivers.controller" in graph["rig.orchestrator.orchestrator"]
    assert "rig.session.log" not in graph["rig.session.run"]  # under TYPE_CHECKING only


@pytest.mark.parametrize("package", ["analysis", "protocols", "drivers", "sim_table", "rig"])
def test_a_package_imports_only_the_layers_below(package: str) -> None:
    assert _breaches(package) == []


def test_every_rig_unit_has_a_layer() -> None:
    units = {_rig_unit(module) for module in _graph() if module.startswith("rig.")}
    assert units - set(RIG_LAYERS) == set(), "a new unit of rig: give it a layer here and in docs/architecture.md"


def test_inside_rig_a_unit_imports_only_its_layer_and_below() -> None:
    breaches = sorted(f"{module} ({_rig_unit(module)}) imports {target} ({_rig_unit(target)})"
                      for module, targets in _graph().items() if module.startswith("rig.")
                      for target in targets if target.startswith("rig.")
                      and RIG_LAYERS.get(_rig_unit(target), 0) > RIG_LAYERS.get(_rig_unit(module), 0))
    assert breaches == []


def test_no_import_circles() -> None:
    assert _import_circles() == []
