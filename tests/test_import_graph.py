"""The package's import graph at run time: no cycle among geosyn's modules, and the rooms'
import rules (experiments never reach into a solver family of the MPC).

Every module of the package is imported with importlib (so the graph is that of the
modules that really load); its edges are read from its source with ast: every ``import``
and ``from ... import`` naming a geosyn module, at module level or inside a function
(a function-level import still closes a cycle when the function runs). Imports under
``if TYPE_CHECKING:`` are left out: they never run. ``from package import name`` is an
edge to ``package.name`` when that is a module, else to ``package``.
"""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

import geosyn

ROOT = Path(geosyn.__file__).resolve().parent


def _module_names() -> list[str]:
    names = ["geosyn"]
    for info in pkgutil.walk_packages([str(ROOT)], prefix="geosyn."):
        names.append(info.name)
    return sorted(names)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement that can run (``if TYPE_CHECKING:`` bodies left out)."""
    out: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out.append(node)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return out


def _resolve(module: str, node: ast.ImportFrom) -> str | None:
    """The absolute module a ``from`` import names (relative imports resolved)."""
    if not node.level:
        return node.module
    package = module.split(".")
    is_package = (ROOT.parent / Path(*package) / "__init__.py").exists()
    base = package if is_package else package[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_graph() -> dict[str, set[str]]:
    """geosyn module -> the geosyn modules it imports (see the module doc)."""
    names = _module_names()
    known = set(names)
    graph: dict[str, set[str]] = {}
    for name in names:
        module = importlib.import_module(name)  # the modules that really load
        source = Path(module.__file__ or "")
        tree = ast.parse(source.read_text(), filename=str(source))
        edges: set[str] = set()
        for node in _imports(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = _resolve(name, node)
                if base is None:
                    continue
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names
                ]
            edges |= {t for t in targets if t in known and t != name}
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as ``[a, b, ..., a]``, or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph):
        if state.get(start):
            continue
        path = [start]
        stack = [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            child = next(stack[-1], None)
            if child is None:
                state[path.pop()] = 2
                stack.pop()
                continue
            if state.get(child) == 1:
                return path[path.index(child) :] + [child]
            if not state.get(child):
                state[child] = 1
                path.append(child)
                stack.append(iter(sorted(graph.get(child, ()))))
    return None


def test_find_cycle_reports_a_planted_cycle() -> None:
    """The cycle search itself, on graphs whose answer is known."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"a2"}, "a2": {"b"}, "b": {"a2"}}) == ["a2", "b", "a2"]


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


def test_no_import_cycle_among_the_package_modules(graph: dict[str, set[str]]) -> None:
    assert len(graph) > 100  # every module was found and imported
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


MPC = "geosyn.controllers.mpc"


def test_experiments_never_import_a_solver_family(graph: dict[str, set[str]]) -> None:
    """`geosyn.experiments` uses the MPC through `geosyn.controllers.mpc`'s public names
    (or `geosyn.controllers`), never one of its modules or solver subpackages."""
    offenders = sorted(
        (src, dst)
        for src, targets in graph.items()
        if src.startswith("geosyn.experiments")
        for dst in targets
        if dst.startswith(MPC + ".")
    )
    assert not offenders, offenders
