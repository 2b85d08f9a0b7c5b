"""Imports point one way: cli -> commands -> edges (io, reports, results, export, history, config,
the simulator's recorder) -> pure packages (slam, control, evaluation, sim models) -> base (data,
errors, params, geodesy, tables). No module imports one in a higher layer, and no modules import each
other in a loop, lazily (inside a function) or not. Read from the source with `ast`, so the rule holds
for imports that only run on some paths too."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mrnc_eval"

# Highest layer first. The longest matching prefix decides a module's layer.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("cli", ("mrnc_eval.cli", "mrnc_eval.__main__")),
    ("commands", ("mrnc_eval.commands", "mrnc_eval.api")),
    ("edges", ("mrnc_eval.io", "mrnc_eval.reports", "mrnc_eval.results", "mrnc_eval.export",
               "mrnc_eval.history", "mrnc_eval.config", "mrnc_eval.sim.recorder")),
    ("pure", ("mrnc_eval.slam", "mrnc_eval.control", "mrnc_eval.evaluation", "mrnc_eval.sim")),
    ("geometry", ("mrnc_eval.geometry",)),  # SE(3), quaternions, resampling: below slam, io, evaluation
    ("base", ("mrnc_eval",)),  # data, errors, params, geodesy, tables, the package itself
)

# Known violations still being removed, each with its reason. An entry that no longer occurs
# fails the test too, so the list can only shrink.
KNOWN_WRONG_WAY: dict[tuple[str, str], str] = {}
KNOWN_CYCLES: dict[frozenset[str], str] = {}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES: dict[str, Path] = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def layer_of(module: str) -> int:
    best_len, best = -1, len(LAYERS) - 1
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best_len:
                best_len, best = len(prefix), index
    return best


def imported_modules(path: Path) -> Iterator[str]:
    """Project modules `path` imports; `from pkg import name` counts as `pkg.name` when that is a module."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names if a.name.split(".")[0] == "mrnc_eval")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] != "mrnc_eval":
                continue
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                yield sub if sub in MODULES else node.module


def import_graph() -> dict[str, set[str]]:
    return {m: {t for t in imported_modules(p) if t in MODULES and t != m} for m, p in MODULES.items()}


def wrong_way_imports(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    # The package root only carries __version__; importing it is not a dependency on a layer.
    return {(m, t) for m, targets in graph.items() for t in targets
            if t != "mrnc_eval" and layer_of(t) < layer_of(m)}


def import_cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    cycles: list[frozenset[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
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
                        cycles.append(frozenset(component))
            elif child not in index:
                index[child] = low[child] = counter
                counter += 1
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return cycles


def test_imports_point_down_the_layers() -> None:
    found = wrong_way_imports(import_graph())
    new = sorted(found - KNOWN_WRONG_WAY.keys())
    assert not new, "imports against the layer order (importer -> imported): " + "; ".join(
        f"{a} ({LAYERS[layer_of(a)][0]}) -> {b} ({LAYERS[layer_of(b)][0]})" for a, b in new)
    gone = sorted(KNOWN_WRONG_WAY.keys() - found)
    assert not gone, f"fixed, remove from KNOWN_WRONG_WAY: {gone}"


def test_no_import_cycles() -> None:
    found = set(import_cycles(import_graph()))
    new = [sorted(c) for c in found - KNOWN_CYCLES.keys()]
    assert not new, f"modules importing each other in a loop: {new}"
    gone = [sorted(c) for c in KNOWN_CYCLES.keys() - found]
    assert not gone, f"fixed, remove from KNOWN_CYCLES: {gone}"


@pytest.mark.parametrize(("importer", "imported", "wrong"), [
    ("mrnc_eval.slam.replay", "mrnc_eval.cli", True),
    ("mrnc_eval.evaluation.ape", "mrnc_eval.io.reader", True),
    ("mrnc_eval.commands.slam", "mrnc_eval.slam.replay", False),
    ("mrnc_eval.sim.recorder", "mrnc_eval.io.writers", False),
    ("mrnc_eval.sim.scene", "mrnc_eval.sim.recorder", True),
])
def test_the_checker_tells_wrong_from_right(importer: str, imported: str, wrong: bool) -> None:
    assert bool(wrong_way_imports({importer: {imported}})) is wrong


def test_the_checker_finds_a_planted_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [frozenset({"a", "b", "c"})]
