"""The static import graph of src/contextros has no circle: every module depends one way.

Read from the syntax tree, not by importing. Every import counts: at module level, inside a
function (a deferred import only hides a circle until the call) and under `if TYPE_CHECKING:`
(type checkers and readers follow it just the same). Importing `a.b.c` also runs
`a/__init__` and `a/b/__init__`; those implicit imports of the enclosing packages are not
edges, else a package whose `__init__` re-exports its modules would be circular with each.
`from package import name` is an edge to `package.name` when that is a module, else to the
package.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "src" / "contextros"


def modules(package: Path) -> dict[str, Path]:
    found: dict[str, Path] = {}
    for path in sorted(package.rglob("*.py")):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def imports(name: str, path: Path, known: dict[str, Path]) -> Iterator[tuple[str, int]]:
    """(imported module, line) for each import in the module `name` of `known`."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in known:
                    yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                kept = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*kept, *([node.module] if node.module else [])])
            for alias in node.names:
                target = f"{base}.{alias.name}"
                if target in known:
                    yield target, node.lineno
                elif base in known:
                    yield base, node.lineno


def circles(package: Path) -> list[list[str]]:
    """The strongly connected components of more than one module (and self-imports)."""
    known = modules(package)
    edges: dict[str, dict[str, int]] = {name: {} for name in known}
    for name, path in known.items():
        for target, line in imports(name, path, known):
            if target != name:
                edges[name].setdefault(target, line)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in edges[node]:
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component: list[str] = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(
                    [
                        f"{member} -> {target} (line {line})"
                        for member in sorted(component)
                        for target, line in sorted(edges[member].items())
                        if target in component
                    ]
                )

    for name in edges:
        if name not in index:
            visit(name)
    return found


def test_src_has_no_import_circle() -> None:
    assert SOURCE.is_dir()
    assert len(modules(SOURCE)) > 50  # the walk found the package
    assert circles(SOURCE) == []


def test_the_check_finds_a_circle_through_a_deferred_or_type_only_import(tmp_path: Path) -> None:
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("from pkg.sub import helper\n")
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "helper.py").write_text("def f():\n    from pkg import a\n")
    (package / "a.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import b\n"
    )
    (package / "b.py").write_text("from .sub.helper import f\n")
    (package / "c.py").write_text("import pkg.a\n")  # one way: no circle
    # `pkg` imports the circle's helper but nothing in it imports `pkg` itself: outside.
    assert circles(package) == [
        [
            "pkg.a -> pkg.b (line 3)",
            "pkg.b -> pkg.sub.helper (line 1)",
            "pkg.sub.helper -> pkg.a (line 2)",
        ]
    ]
