"""The layers of docs/architecture.md, read from the imports as they are (``ast``, nothing imported), and the
import circles between modules (run-time, deferred or typing-only imports alike).

A rule broken today is marked ``xfail(strict=True)`` with the import that breaks it: the test documents the
debt and fails (XPASS) once it is paid — then remove the mark and update docs/architecture.md.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from functools import cache
from itertools import pairwise
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


KINDS = ("run-time", "deferred", "typing-only")
"""How a module imports another: at its top level (when it is imported), inside a function (when that runs), or
only under ``if TYPE_CHECKING:`` (for the type checker)."""


def _module_imports(tree: ast.AST, module: str, is_package: bool) -> Iterator[tuple[str, str]]:
    """``(imported module, kind)`` of every import in a module's tree, relative imports resolved."""
    package = module if is_package else module.rpartition(".")[0]

    def walk(node: ast.AST, kind: str) -> Iterator[tuple[str, str]]:
        for child in ast.iter_child_nodes(node):
            child_kind = kind
            if _type_checking_only(child):
                child_kind = "typing-only"
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) and kind == "run-time":
                child_kind = "deferred"
            if isinstance(child, ast.Import):
                yield from ((alias.name, child_kind) for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    parent = package.split(".")[: len(package.split(".")) - child.level + 1]
                    base = ".".join([*parent, *([base] if base else [])])
                yield base, child_kind
                yield from ((f"{base}.{alias.name}", child_kind) for alias in child.names)
            yield from walk(child, child_kind)

    yield from walk(tree, "run-time")


@cache
def _module_graph() -> dict[str, dict[str, str]]:
    """Each of our modules → the modules of ours it imports, with the strongest kind of import (run-time before
    deferred before typing-only). ``from pkg import sub`` counts as importing ``pkg.sub`` only; a module importing
    its own package (whose ``__init__`` has run before it) is no edge."""
    paths = {_module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}
    graph: dict[str, dict[str, str]] = {}
    for name, path in paths.items():
        tree = ast.parse(path.read_text(), str(path))
        edges: dict[str, str] = {}
        for imported, kind in _module_imports(tree, name, path.name == "__init__.py"):
            ours = imported in paths and imported != name and not name.startswith(imported + ".")
            if ours and (imported not in edges or KINDS.index(kind) < KINDS.index(edges[imported])):
                edges[imported] = kind
        graph[name] = {target: kind for target, kind in edges.items()
                       if not any(other.startswith(target + ".") and kind == edges[other] for other in edges)}
    return graph


def _module_circles(graph: dict[str, dict[str, str]]) -> list[str]:
    """Every strongly connected group of modules (Tarjan), each as one circle through it with the kind of each
    edge: ``a -(run-time)-> b -(deferred)-> a``."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for target in graph.get(node, {}):
            if target not in index:
                connect(target)
                low[node] = min(low[node], low[target])
            elif target in stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    return sorted(_circle_through(graph, group) for group in groups)


def _circle_through(graph: dict[str, dict[str, str]], group: list[str]) -> str:
    """The shortest circle from the group's first module back to it, inside the group, written with its edges."""
    start, members = group[0], set(group)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for target in sorted(graph[node]):
                if target == start:
                    path = [*paths[node], start]
                    return " ".join(f"{a} -({graph[a][b]})->" for a, b in pairwise(path)) + f" {start}"
                if target in members and target not in paths:
                    paths[target] = [*paths[node], target]
                    following.append(target)
        frontier = following
    raise AssertionError(f"no circle through {group}")


def test_the_module_graph_sees_relative_deferred_and_typing_only_imports() -> None:
    source = ("from typing import TYPE_CHECKING\nfrom . import sibling\nfrom ..other import thing\n"
              "if TYPE_CHECKING:\n    from .typed import T\n"
              "def f():\n    import pkg.late\n    if TYPE_CHECKING:\n        import pkg.hint\n")
    found = set(_module_imports(ast.parse(source), "pkg.sub.mod", is_package=False))
    assert {("pkg.sub.sibling", "run-time"), ("pkg.other.thing", "run-time"), ("pkg.sub.typed", "typing-only"),
            ("pkg.late", "deferred"), ("pkg.hint", "typing-only")} <= found
    assert set(_module_imports(ast.parse("from . import a"), "pkg", is_package=True)) >= {("pkg.a", "run-time")}
    assert _module_graph()["rig.session.log"]["rig.session.writer"] == "run-time"  # from .writer import BlockWriter


def test_the_circle_finder_names_each_edge_s_kind() -> None:
    graph = {"a": {"b": "run-time"}, "b": {"c": "deferred"}, "c": {"a": "typing-only"}, "d": {"a": "run-time"}}
    assert _module_circles(graph) == ["a -(run-time)-> b -(deferred)-> c -(typing-only)-> a"]
    assert _module_circles({"a": {"b": "run-time"}, "b": {}}) == []


def test_no_import_circles_between_modules() -> None:
    """Any circle fails, whatever its kind: a deferred import is a circle that waits for a call, a typing-only one
    a circle for every reader of the code."""
    assert _module_circles(_module_graph()) == []
