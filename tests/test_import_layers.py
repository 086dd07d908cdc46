"""The package's floors: every import of `src/` (function-level and
`TYPE_CHECKING` ones included, and modules named by string for
`importlib`) against the layer drawing of `docs/architecture.md`.

A module may import its own package and any lower layer, never a higher
one or a neighbour on its own layer; and no modules import each other in a
circle.
"""

from __future__ import annotations

import ast
import functools
import re
from collections.abc import Iterator
from itertools import pairwise
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "fastcs_ethercat"
SOURCE = ROOT / "src" / PACKAGE
DRAWING = ROOT / "docs" / "architecture.md"
ANY_ROOT_MODULE = "*.py"
"""The drawing's token for every module at the package root it does not name."""

MODULE_STRING = re.compile(rf"^{PACKAGE}(\.[a-z_][a-z0-9_]*)+$")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SOURCE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def all_modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted(SOURCE.rglob("*.py"))}


def imported(path: Path, name: str, modules: dict[str, Path]) -> Iterator[str]:
    """Every package module `path` imports, wherever the import stands."""
    here = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    run_as_child = {id(node) for node in ast.walk(tree) for node in _after_dash_m(node)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = here.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            # `from package import submodule` imports the submodule
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                for alias in node.names
            ]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            found = MODULE_STRING.match(node.value) and id(node) not in run_as_child
            targets = [node.value] if found else []
        else:
            continue
        yield from (target for target in targets if target in modules)


def _after_dash_m(node: ast.AST) -> list[ast.AST]:
    """The module of a `python -m module` command line: a child process's
    program, not an import."""
    if not isinstance(node, (ast.List, ast.Tuple)):
        return []
    items = node.elts
    return [
        after
        for before, after in pairwise(items)
        if isinstance(before, ast.Constant) and before.value == "-m"
    ]


@functools.cache
def import_graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {
        name: set(imported(path, name, modules)) - {name}
        for name, path in modules.items()
    }


def drawn_layers() -> list[list[str]]:
    """The Layers drawing, top floor first: each floor's leading tokens that
    name a package (`ioc/`) or a root module (`process.py`)."""
    text = DRAWING.read_text(encoding="utf-8")
    section = text.split("## Layers", 1)[1]
    block = section.split("```", 2)[1]
    layers: list[list[str]] = []
    for line in block.splitlines():
        names: list[str] = []
        for token in line.split():
            if not token.endswith(("/", ".py")):
                break
            names.append(token)
        if names:
            layers.append(names)
    return layers


def floor_of(module: str, floors: dict[str, int]) -> tuple[int, str]:
    """(floor number, counting from the top, and the drawn name) of a module."""
    parts = module.split(".")
    if len(parts) == 1:
        drawn = "__init__.py"
    elif (SOURCE / parts[1] / "__init__.py").exists():
        drawn = f"{parts[1]}/"
    else:
        drawn = f"{parts[1]}.py"
    if drawn in floors:
        return floors[drawn], drawn
    if drawn.endswith(".py") and ANY_ROOT_MODULE in floors:
        return floors[ANY_ROOT_MODULE], ANY_ROOT_MODULE
    raise AssertionError(f"{module}: {drawn} is not drawn in {DRAWING.name}'s Layers")


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for after in sorted(graph[node]):
            if after not in index:
                visit(after)
                low[node] = min(low[node], low[after])
            elif after in on_stack:
                low[node] = min(low[node], index[after])
        if low[node] == index[node]:
            group: list[str] = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_drawing_names_each_package_once() -> None:
    names = [name for layer in drawn_layers() for name in layer]
    assert len(names) == len(set(names)), names
    packages = {f"{path.parent.name}/" for path in SOURCE.glob("*/__init__.py")}
    assert packages <= set(names), sorted(packages - set(names))


def test_no_module_imports_a_higher_floor_or_a_neighbour() -> None:
    floors = {
        name: number for number, layer in enumerate(drawn_layers()) for name in layer
    }
    wrong = []
    for module, targets in import_graph().items():
        floor, drawn = floor_of(module, floors)
        for target in sorted(targets):
            target_floor, target_drawn = floor_of(target, floors)
            if target_drawn == drawn and drawn != ANY_ROOT_MODULE:
                continue  # within one package
            if target_floor <= floor and target != PACKAGE:
                wrong.append(f"{module} ({drawn}) -> {target} ({target_drawn})")
    assert wrong == [], "\n".join(wrong)


def test_no_circles() -> None:
    found = circles(import_graph())
    assert found == [], "\n".join(" <-> ".join(group) for group in found)


def test_the_graph_sees_function_level_and_string_imports() -> None:
    graph = import_graph()
    assert f"{PACKAGE}.cli.terminals" in graph[f"{PACKAGE}.cli"]  # importlib table
    assert f"{PACKAGE}.errors" in graph[f"{PACKAGE}.bounded"]
