"""The package's imports point down its layers, and no module imports itself round a circle.

Every `from rcmlconf... import` counts, those under TYPE_CHECKING and inside functions too: a
circle of type names is still two modules that cannot be read, or moved, one without the other.
"""

from __future__ import annotations

import ast
import graphlib
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "rcmlconf"

#: The layers the developers' guide names, lowest first: none imports one after it.
LAYERS = ["values", "rcml", "rctp", "rsp", "reference", "conformance", "cli"]


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports() -> dict[str, set[str]]:
    """Each module of the package -> the modules of the package it imports."""
    modules = {module_name(path): path for path in ROOT.rglob("*.py")}
    found: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                for alias in node.names:
                    whole = f"{node.module}.{alias.name}"
                    target = whole if whole in modules else node.module
                    if target in modules and target != name:
                        found[name].add(target)
    return found


def layer(module: str) -> str:
    return module.split(".")[1] if "." in module else ""


def test_the_layers_import_only_down() -> None:
    graph: dict[str, set[str]] = defaultdict(set)
    for module, targets in imports().items():
        for target in targets:
            if layer(module) != layer(target):
                graph[layer(module)].add(layer(target))
    try:
        order = list(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as circle:
        raise AssertionError(f"subpackages import each other: {circle.args[1]}") from None
    named = [name for name in order if name in LAYERS]
    assert named == LAYERS, named
    upward = {
        (low, high)
        for low in LAYERS
        for high in graph[low]
        if high in LAYERS and LAYERS.index(high) > LAYERS.index(low)
    }
    assert not upward, upward


def circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan's, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, targets = work[-1]
            step = next(targets, None)
            if step is not None:
                if step not in index:
                    index[step] = low[step] = len(index)
                    stack.append(step)
                    on_stack.add(step)
                    work.append((step, iter(sorted(graph[step]))))
                elif step in on_stack:
                    low[node] = min(low[node], index[step])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def test_no_module_imports_itself_round_a_circle() -> None:
    """Where two modules' types must name each other, one names a Protocol of what it needs of
    the other (`registry` and `context`'s `CaseRules`, `rsp_probe`'s `HandDriven`)."""
    found = circles(imports())
    assert not found, sorted(sorted(circle) for circle in found)


def test_a_circle_is_found() -> None:
    """The search itself: a circle of three, and a tail that is not in it."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [frozenset({"a", "b", "c"})]
