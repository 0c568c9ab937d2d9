"""The import graph of the three packages: no cycles, and imports run one way.

Every import counts, at module level or inside a function, and so does
``importlib.import_module`` with a literal name; only imports under ``if TYPE_CHECKING:`` are
left out, since they never run. An edge goes to the module imported: ``from evolution.runner
import RunConfig`` is an edge to ``evolution.runner`` (its ``__init__``), ``from evolution.lab
import api`` one to ``evolution.lab.api``.

The rules (docs/design.md §2):

- no cycle of modules importing each other;
- ``evolution → behaviours → cyber_rodent``: ``cyber_rodent`` never imports the other two, and
  ``behaviours`` never imports ``evolution``;
- evolution's science core never imports its experiment tooling, ``evolution.lab``;
- the command line, ``evolution.cli``, is the top floor: it may import all of them, and nothing
  outside it imports it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("cyber_rodent", "behaviours", "evolution")


def _modules() -> dict[str, Path]:
    """Every module of the three packages by dotted name (a package by its ``__init__``)."""
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imported_names(module: str, path: Path) -> list[str]:
    """The dotted names ``module`` imports, at any depth except under ``TYPE_CHECKING``."""
    is_package = path.name == "__init__.py"
    names: list[str] = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for other in child.orelse:
                    visit(other)
                continue
            if isinstance(child, ast.Import):
                names.extend(alias.name for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    anchor = module.split(".")
                    anchor = anchor if is_package else anchor[:-1]
                    anchor = anchor[: len(anchor) - (child.level - 1)]
                    base = ".".join([*anchor, base] if base else anchor)
                # ``from a.b import c``: the module a.b.c if there is one, else a.b
                names.extend(f"{base}.{alias.name}" for alias in child.names)
            elif (
                isinstance(child, ast.Call)
                and isinstance(child.func, ast.Attribute | ast.Name)
                and getattr(child.func, "attr", getattr(child.func, "id", "")) == "import_module"
                and child.args
                and isinstance(child.args[0], ast.Constant)
                and isinstance(child.args[0].value, str)
            ):
                names.append(child.args[0].value)
            visit(child)

    visit(ast.parse(path.read_text(), str(path)))
    return names


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of the three packages it imports."""
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        targets = set()
        for name in _imported_names(module, path):
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                targets.add(name)
        graph[module] = targets
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                connect(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    return sorted(found)


def _top(module: str) -> str:
    return module.split(".")[0]


def _in_cli(module: str) -> bool:
    return module == "evolution.cli" or module.startswith("evolution.cli.")


def test_the_checker_finds_a_cycle_and_a_function_level_import(tmp_path: Path) -> None:
    """The checker itself: a cycle closed by an import inside a function is found."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [["a", "b", "c"]]
    source = tmp_path / "m.py"
    source.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import evolution.lab\n"
        "def f():\n    from evolution.runner import config\n"
        "    importlib.import_module('behaviours.kernels')\n"
    )
    names = _imported_names("evolution.m", source)
    assert "evolution.runner.config" in names and "behaviours.kernels" in names
    assert "evolution.lab" not in names


def test_no_import_cycles(capsys: pytest.CaptureFixture[str]) -> None:
    graph = import_graph()
    found = cycles(graph)
    with capsys.disabled():
        edges = sum(len(t) for t in graph.values())
        print(f"\nimport graph: {len(graph)} modules, {edges} imports, {len(found)} cycles")
    assert found == [], "modules that import each other: " + "; ".join(
        " <-> ".join(c) for c in found
    )


def test_imports_run_one_way() -> None:
    """``evolution → behaviours → cyber_rodent``, and the core never imports the tooling."""
    order = {"cyber_rodent": 0, "behaviours": 1, "evolution": 2}
    wrong = []
    for module, targets in import_graph().items():
        for target in targets:
            upward = order[_top(target)] > order[_top(module)]
            into_lab = (
                target.startswith("evolution.lab")
                and _top(module) == "evolution"
                and not module.startswith("evolution.lab")
                and not _in_cli(module)
            )
            if upward or into_lab:
                wrong.append(f"{module} -> {target}")
    assert wrong == []


def test_lower_packages_never_import_upper_ones() -> None:
    """Not even a command line of its own: ``cyber_rodent`` imports neither ``behaviours`` nor
    ``evolution``, and ``behaviours`` does not import ``evolution``."""
    above = {"cyber_rodent": {"behaviours", "evolution"}, "behaviours": {"evolution"}}
    graph = import_graph()
    assert any(_top(module) == "cyber_rodent" for module in graph)
    for package, upper in above.items():
        wrong = [
            f"{module} -> {target}"
            for module, targets in graph.items()
            if _top(module) == package
            for target in targets
            if _top(target) in upper
        ]
        assert wrong == [], f"{package} imports a package above it"


def test_the_command_line_is_the_top_floor() -> None:
    """``evolution.cli`` ties the three packages together, and none of them imports it."""
    graph = import_graph()
    assert {_top(t) for m, ts in graph.items() if _in_cli(m) for t in ts} == {
        "cyber_rodent",
        "behaviours",
        "evolution",
    }
    wrong = [
        f"{module} -> {target}"
        for module, targets in graph.items()
        if not _in_cli(module)
        for target in targets
        if _in_cli(target)
    ]
    assert wrong == []
