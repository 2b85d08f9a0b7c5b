"""Imports point one way: cli -> commands -> edges (io, reports, results, export, history, config,
recording: the simulator's log recorder) -> pure packages (slam, control, evaluation, sim models) ->
geometry -> base (data, errors, params, geodesy, tables). No module imports one in a higher layer, no
pure package reaches sideways into another pure package, no modules import each other in a loop,
lazily (inside a function) or not, and no import is relative. Read from the source with `ast`, so
the rules hold for imports that only run on some paths too. A module's layer is its top-level
folder's (or, for a module directly in the package, its own): the folders show the layers."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mrnc_eval"

# Highest layer first: each top-level folder and module of the package, by name. A new folder or
# module must be placed here (test_every_folder_has_a_layer).
LAYERS: tuple[tuple[str, frozenset[str]], ...] = (
    ("cli", frozenset({"cli", "__main__", "cli_help", "cli_evo", "cli_fast"})),
    ("commands", frozenset({"commands", "api"})),
    ("edges", frozenset({"io", "reports", "results", "export", "history", "config", "recording",
                        "outputs"})),  # outputs: the one overwrite rule every writer calls
    ("pure", frozenset({"slam", "control", "evaluation", "sim"})),
    ("geometry", frozenset({"geometry"})),  # SE(3), quaternions, resampling, point fits: below slam, io, evaluation
    # schema: the names inside a result folder, shared by writers and readers; extras: which install a verb needs;
    # gc_pause: the collector paused while `slam` starts up (cli and commands call it)
    ("base", frozenset({"__init__", "data", "errors", "params", "geodesy", "tables", "text", "spelling", "peaks",
                        "schema", "extras", "gc_pause"})),
)
PURE = "pure"  # packages of this layer import only themselves and the layers below

# Known violations still being removed, each with its reason. An entry that no longer occurs
# fails the test too, so the list can only shrink.
KNOWN_WRONG_WAY: dict[tuple[str, str], str] = {}
_CONTROL_RUNS = ("the per-run control evaluation (evaluation/control_run.py, evaluation/disturbance.py) runs the "
                 "chain on a scenario and scores it; it belongs in a control-evaluation package of its own")
KNOWN_SIDEWAYS: dict[tuple[str, str], str] = {
    ("mrnc_eval.evaluation.control_metrics", "mrnc_eval.control.config"):
        "Table II metrics take control's MetricsConfig sections; they move with the control issue",
    ("mrnc_eval.control.replay", "mrnc_eval.evaluation.control_metrics"):
        "the replay loop scores each recorded segment as it goes; " + _CONTROL_RUNS,
    **{("mrnc_eval.evaluation.control_run", f"mrnc_eval.control.{m}"): _CONTROL_RUNS
       for m in ("closed_loop", "config", "kinematics", "raid", "scenario")},
    **{("mrnc_eval.evaluation.disturbance", f"mrnc_eval.control.{m}"): _CONTROL_RUNS
       for m in ("closed_loop", "config", "plant", "scenario")},
}
KNOWN_CYCLES: dict[frozenset[str], str] = {}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES: dict[str, Path] = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def top_of(module: str) -> str:
    """The top-level folder or module a module lives in ("__init__" for the package itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def layer_of(module: str) -> int:
    top = top_of(module)
    for index, (_, names) in enumerate(LAYERS):
        if top in names:
            return index
    raise KeyError(f"{module}: its folder {top!r} has no layer in LAYERS")


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


def relative_imports(source: str) -> list[int]:
    """Line numbers of `from . import x` / `from .mod import x`."""
    return [n.lineno for n in ast.walk(ast.parse(source)) if isinstance(n, ast.ImportFrom) and n.level > 0]


def import_graph() -> dict[str, set[str]]:
    return {m: {t for t in imported_modules(p) if t in MODULES and t != m} for m, p in MODULES.items()}


def wrong_way_imports(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    # The package root only carries __version__; importing it is not a dependency on a layer.
    return {(m, t) for m, targets in graph.items() for t in targets
            if t != "mrnc_eval" and layer_of(t) < layer_of(m)}


def sideways_imports(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    """Imports from one pure package into another (slam -> evaluation...): each pure package is a
    unit that the others do not reach into; what two of them share goes down to geometry or base."""
    pure = next(i for i, (name, _) in enumerate(LAYERS) if name == PURE)
    return {(m, t) for m, targets in graph.items() for t in targets
            if layer_of(m) == pure and layer_of(t) == pure and top_of(m) != top_of(t)}


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


def test_pure_packages_do_not_import_each_other() -> None:
    found = sideways_imports(import_graph())
    new = sorted(found - KNOWN_SIDEWAYS.keys())
    assert not new, "imports between pure packages (importer -> imported): " + "; ".join(f"{a} -> {b}" for a, b in new)
    gone = sorted(KNOWN_SIDEWAYS.keys() - found)
    assert not gone, f"fixed, remove from KNOWN_SIDEWAYS: {gone}"


def test_no_relative_imports() -> None:
    found = [f"{name}:{line}" for name, path in sorted(MODULES.items())
             for line in relative_imports(path.read_text(encoding="utf-8"))]
    assert not found, f"relative imports (write mrnc_eval.x.y): {found}"
    assert relative_imports("from . import lie\nfrom .se3 import make\nfrom mrnc_eval import data\n") == [1, 2]


def test_every_folder_has_a_layer() -> None:
    tops = {top_of(m) for m in MODULES}
    placed = set().union(*(names for _, names in LAYERS))
    assert not tops - placed, f"place these in LAYERS: {sorted(tops - placed)}"
    assert not placed - tops, f"no longer in the package, remove from LAYERS: {sorted(placed - tops)}"


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
    ("mrnc_eval.recording.recorder", "mrnc_eval.io.writers", False),
    ("mrnc_eval.sim.scene", "mrnc_eval.recording.recorder", True),
    ("mrnc_eval.sim.recorder", "mrnc_eval.io.writers", True),  # an edge inside a pure folder is refused
    ("mrnc_eval.geometry.lie", "mrnc_eval.slam.se3", True),
])
def test_the_checker_tells_wrong_from_right(importer: str, imported: str, wrong: bool) -> None:
    assert bool(wrong_way_imports({importer: {imported}})) is wrong


@pytest.mark.parametrize(("importer", "imported", "sideways"), [
    ("mrnc_eval.slam.gnss", "mrnc_eval.evaluation.align", True),
    ("mrnc_eval.sim.imu", "mrnc_eval.control.plant", True),
    ("mrnc_eval.slam.gnss", "mrnc_eval.geometry.point_fit", False),
    ("mrnc_eval.slam.replay", "mrnc_eval.slam.graph", False),
    ("mrnc_eval.io.reader", "mrnc_eval.results", False),  # edges may use each other
])
def test_the_checker_tells_sideways_from_down(importer: str, imported: str, sideways: bool) -> None:
    assert bool(sideways_imports({importer: {imported}})) is sideways


def test_the_checker_finds_a_planted_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [frozenset({"a", "b", "c"})]
