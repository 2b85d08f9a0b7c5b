"""The shape rules of docs/architecture.md that a reviewer would otherwise check by eye, read
from the source with `ast`: hand-off dataclasses are built by keyword."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "mrnc_eval"
HANDOFF_HOMES = ("slam/", "commands/", "results.py")  # where the central hand-offs live
MAX_POSITIONAL = 3  # a point (x, y, z) or a pair may be positional; a hand-off of more is built by keyword


def _parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def _decorator_call(node: ast.ClassDef) -> ast.Call | ast.expr | None:
    for deco in node.decorator_list:
        func = deco.func if isinstance(deco, ast.Call) else deco
        if (func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")) == "dataclass":
            return deco
    return None


def _dataclasses(homes: tuple[str, ...] = HANDOFF_HOMES) -> dict[str, ast.ClassDef]:
    """Dataclasses defined in the hand-off homes, by class name."""
    out: dict[str, ast.ClassDef] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).as_posix().startswith(homes):
            out.update({n.name: n for n in ast.walk(_parse(path))
                        if isinstance(n, ast.ClassDef) and _decorator_call(n) is not None})
    return out


def _is_kw_only(node: ast.ClassDef) -> bool:
    deco = _decorator_call(node)
    return isinstance(deco, ast.Call) and any(
        k.arg == "kw_only" and isinstance(k.value, ast.Constant) and k.value.value is True for k in deco.keywords)


def positional_builds(tree: ast.Module, names: set[str], where: str) -> list[str]:
    """Calls of the named classes (also `cls(...)` in their own class methods) with more than
    MAX_POSITIONAL positional arguments."""
    out = []
    for cls in [n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)] + [tree]:
        own = cls.name if isinstance(cls, ast.ClassDef) else None
        for node in ast.walk(cls):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name == "cls" and own in names:
                name = own
            if name in names and len(node.args) > MAX_POSITIONAL:
                out.append(f"{where}:{node.lineno} {name}(...) with {len(node.args)} positional arguments")
    return sorted(set(out))


def test_handoffs_are_built_by_keyword() -> None:
    names = set(_dataclasses())
    found = [hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in positional_builds(_parse(path), names, str(path.relative_to(PACKAGE.parent)))]
    assert not found, "build these by keyword: " + "; ".join(found)


def test_the_central_handoffs_are_keyword_only() -> None:
    classes = _dataclasses()
    for name in ("SlamOutput", "MatchResult", "LogInputs", "RunResult", "Metric", "Event"):
        assert _is_kw_only(classes[name]), f"{name} is not @dataclass(kw_only=True)"
    # every hand-off, not just those: configuration sections (built from YAML by keyword) aside
    loose = sorted(n for n, c in classes.items() if not n.endswith("Config") and not _is_kw_only(c))
    assert not loose, f"dataclasses in {HANDOFF_HOMES} without kw_only=True: {loose}"


def test_the_positional_check_finds_a_planted_build() -> None:
    planted = ast.parse("out = SlamOutput(a, b, c, d)\n"
                        "class MatchResult:\n"
                        "    @classmethod\n"
                        "    def empty(cls): return cls(1, 2, 3, 4, 5)\n"
                        "ok = SlamOutput(a, b, c, stamps=d)\n")
    assert len(positional_builds(planted, {"SlamOutput", "MatchResult"}, "x")) == 2


def untyped_readers(tree: ast.Module, where: str) -> list[str]:
    """Parameters that hold an open log (`lg`, `reader`) without the LogReader annotation."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            for arg in node.args.posonlyargs + node.args.args + node.args.kwonlyargs:
                if arg.arg in ("lg", "reader", "log_reader") and (
                        arg.annotation is None or ast.unparse(arg.annotation) != "LogReader"):
                    out.append(f"{where}:{node.lineno} {arg.arg}: "
                               f"{ast.unparse(arg.annotation) if arg.annotation else 'unannotated'}")
    return out


def test_the_commands_take_a_typed_log_reader() -> None:
    """With mypy's untyped-def checks on mrnc_eval.commands.* (pyproject.toml), a renamed
    LogReader method fails the type check instead of a run."""
    found = [hit for path in sorted((PACKAGE / "commands").glob("*.py"))
             for hit in untyped_readers(_parse(path), path.name)]
    assert not found, f"annotate these as LogReader: {found}"
    planted = ast.parse("def f(lg, x: int): ...\ndef g(lg: Any): ...\ndef h(lg: LogReader): ...\n")
    assert len(untyped_readers(planted, "x")) == 2
    pyproject = (PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8")
    assert 'module = ["mrnc_eval.commands.*"]\ndisallow_untyped_defs = true' in pyproject


def literal_tolerances(tree: ast.Module, where: str) -> list[str]:
    """Calls that pass a number as `max_diff` (a stamp-pairing tolerance belongs in evaluation/config.py)."""
    return [f"{where}:{n.lineno} max_diff={ast.unparse(k.value)}" for n in ast.walk(tree) if isinstance(n, ast.Call)
            for k in n.keywords if k.arg == "max_diff" and isinstance(k.value, ast.Constant)]


def test_the_ground_truth_pairing_tolerance_has_one_home() -> None:
    import inspect

    from mrnc_eval import cli
    from mrnc_eval.evaluation.config import EvaluationConfig

    found = [hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in literal_tolerances(_parse(path), str(path.relative_to(PACKAGE)))]
    assert not found, f"use evaluation.gt_max_diff_s / gnss_max_diff_s / max_diff_s: {found}"
    assert literal_tolerances(ast.parse("ape(gt, est, max_diff=0.02)"), "x")  # the check sees a planted one
    # a slam result's APE is the one `mrnc-eval ape` gives on its files with the default --max-diff
    for verb in (cli.ape, cli.rpe):
        assert inspect.signature(verb).parameters["max_diff"].default == EvaluationConfig().gt_max_diff_s
    assert EvaluationConfig().max_diff_s == EvaluationConfig().gt_max_diff_s


MAX_FUNCTION_LINES = 50
COMPILED = {"njit", "jit", "kernel", "vectorize", "guvectorize"}  # numba kernels: one loop body, kept whole
# Known long functions still being split, each with its reason; an entry that is fixed fails the test.
KNOWN_LONG: dict[str, str] = {
    "commands/control.py:run_log": "the control verb's replay/simulate dispatch; restructured by the control issue",
}


def long_functions(tree: ast.Module, where: str, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """Functions (and methods) longer than `limit` lines, decorator and docstring included,
    compiled kernels aside."""
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        decorators = {(d.func if isinstance(d, ast.Call) else d) for d in node.decorator_list}
        names = {d.attr if isinstance(d, ast.Attribute) else getattr(d, "id", "") for d in decorators}
        if names & COMPILED:
            continue
        if node.end_lineno is not None and node.end_lineno - node.lineno + 1 > limit:
            out.append(f"{where}:{node.name}")
    return out


def test_no_function_over_50_lines() -> None:
    found = {hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in long_functions(_parse(path), path.relative_to(PACKAGE).as_posix())}
    new = sorted(found - KNOWN_LONG.keys())
    assert not new, f"functions over {MAX_FUNCTION_LINES} lines (split into named steps): {new}"
    gone = sorted(KNOWN_LONG.keys() - found)
    assert not gone, f"fixed, remove from KNOWN_LONG: {gone}"
    planted = ast.parse("def f():\n" + "    x = 1\n" * 60 + "@njit(cache=True)\ndef g():\n" + "    x = 1\n" * 60)
    assert long_functions(planted, "x") == ["x:f"]


def broad_handlers(tree: ast.Module, where: str) -> list[str]:
    """`except Exception` handlers (alone or in a tuple)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ExceptHandler) and node.type is not None:
            caught = node.type.elts if isinstance(node.type, ast.Tuple) else [node.type]
            if any(isinstance(c, ast.Name) and c.id == "Exception" for c in caught):
                out.append(f"{where}:{node.lineno}")
    return out


def test_the_io_boundary_catches_library_errors_by_type() -> None:
    """A bug of ours in io/ or export/ (AttributeError, TypeError...) must not become "corrupted
    data" (exit 4): the libraries' errors are caught by type (io/library_errors.py)."""
    found = [hit for folder in ("io", "export") for path in sorted((PACKAGE / folder).rglob("*.py"))
             for hit in broad_handlers(_parse(path), path.relative_to(PACKAGE).as_posix())]
    assert not found, f"catch the library's error types instead: {found}"
    assert broad_handlers(ast.parse("try: f()\nexcept (OSError, Exception): pass\n"), "x") == ["x:2"]
    pyproject = (PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8")
    assert '"BLE"' in pyproject.split("[tool.ruff.lint]")[1].split("\n[")[0]  # ruff's blind-except rule is on


def test_a_bug_in_our_code_is_not_reported_as_corrupt_data(tmp_path: Path) -> None:
    """Negative control of the above: an AttributeError while decoding passes through the reader
    (exit 5, a bug) while a library's parse error becomes an InputError (exit 4)."""
    import pytest

    from mrnc_eval.errors import InputError
    from mrnc_eval.io import open_log

    with open_log(PACKAGE.parent / "sample_logs" / "loop_forest.bag") as lg:
        topic = lg.roles["imu"]

        def buggy(raw: bytes, topic: str) -> object:
            raise AttributeError("our bug")

        def broken(raw: bytes, topic: str) -> object:
            raise IndexError("buffer too short")

        lg.source.src.deserialize = buggy
        with pytest.raises(AttributeError):
            next(lg.messages(topic))
        lg.source.src.deserialize = broken
        with pytest.raises(InputError, match="cannot decode"):
            next(lg.messages(topic))
