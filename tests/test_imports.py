"""The package's imports form no circle (issue 67: tasks/expert -> navigation -> starts ->
expert was one; issue 78: it remained through the expert's type annotations).

A module's imports are read from its source: every ``import`` and ``from ... import``, at
module level or inside a function (a function-level import still runs), and, where asked, those
under ``if TYPE_CHECKING:``, which never run but still say which module a module is written
against. ``from package import name`` counts as importing ``package.name`` where that is a
module, else ``package``.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sim4endor"


def _module_names() -> dict[str, Path]:
    names = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


class _Imports(ast.NodeVisitor):
    def __init__(self, name: str, is_package: bool, modules: set[str],
                 type_checking: bool) -> None:
        self.name, self.is_package, self.modules = name, is_package, modules
        self.type_checking = type_checking
        self.found: set[str] = set()

    def visit_If(self, node: ast.If) -> None:
        test = node.test
        if not self.type_checking and (getattr(test, "id", None) == "TYPE_CHECKING"
                                       or getattr(test, "attr", None) == "TYPE_CHECKING"):
            for statement in node.orelse:
                self.visit(statement)
            return
        self.generic_visit(node)

    def visit_Import(self, node: ast.Import) -> None:
        self.found.update(alias.name for alias in node.names)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        base = node.module or ""
        if node.level:
            package = self.name.split(".")
            package = package if self.is_package else package[:-1]
            base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
        for alias in node.names:
            sub = f"{base}.{alias.name}"
            self.found.add(sub if sub in self.modules else base)


def import_graph(type_checking: bool = False) -> dict[str, set[str]]:
    """Each module of the package and the package's modules it imports (with
    ``type_checking``, also those imported only under ``if TYPE_CHECKING:``)."""
    modules = _module_names()
    graph = {}
    for name, path in modules.items():
        visitor = _Imports(name, path.name == "__init__.py", set(modules), type_checking)
        visitor.visit(ast.parse(path.read_text()))
        graph[name] = {m for m in visitor.found if m in modules and m != name}
    return graph


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_finder_sees_a_circle() -> None:
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_the_package_imports_form_no_circle() -> None:
    graph = import_graph()
    assert "sim4endor.tasks.steering" in graph["sim4endor.tasks.starts"]  # the graph is read
    assert circles(graph) == []


def test_the_tasks_form_no_circle_even_in_their_type_annotations() -> None:
    # The start poses steer with the expert's steering (tasks.steering), which reads no task:
    # the expert builds on it and on the task, and nothing below the expert names the expert.
    graph = import_graph(type_checking=True)
    tasks = {name: {m for m in imported if _within(m, "sim4endor.tasks")}
             for name, imported in graph.items() if _within(name, "sim4endor.tasks")}
    assert "sim4endor.tasks.navigation" in tasks["sim4endor.tasks.expert"]  # the graph is read
    assert circles(tasks) == []


def test_the_libraries_import_no_command_line() -> None:
    # The command line (sim4endor.cli) is built on the vessels, models and tasks; its shared
    # argument types live below all of them, in sim4endor._argtypes.
    graph = import_graph(type_checking=True)
    assert graph["sim4endor._argtypes"] == set()
    libraries = ("sim4endor.vessels", "sim4endor.models", "sim4endor.tasks")
    for name, imported in graph.items():
        if any(_within(name, library) for library in libraries):
            assert not {m for m in imported if _within(m, "sim4endor.cli")}, name


def test_the_models_import_nothing_built_on_them() -> None:
    # sim4endor.physics builds on the models; the bench tests that drive the physics live in
    # sim4endor.benches, above it (issue 67).
    graph = import_graph()
    above = {"sim4endor.physics", "sim4endor.suite", "sim4endor.benches"}
    for name, imported in graph.items():
        if name.startswith("sim4endor.models"):
            assert not {m for m in imported if m.split(".")[:2] != ["sim4endor", "models"]
                        and any(m == a or m.startswith(a + ".") for a in above)}, name
