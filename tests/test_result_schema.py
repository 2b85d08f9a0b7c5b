"""The result schema (mrnc_eval/schema/): every series and extra key a reader of result folders
uses (the report, its figures, the MCAP export, the table) is one a command writes, read from the
source with `ast`. A renamed or dropped series fails here instead of making a figure vanish."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "mrnc_eval"
WRITERS = ("commands/slam.py", "commands/control.py", "commands/log_job.py", "commands/control_sweep.py")
READERS = ("reports/figures.py", "reports/render.py", "export/topics.py", "commands/export.py", "commands/table.py")
RESULT_MAPS = ("series", "extra", "s")  # result.series, r.extra and figures' `s = r.series`


def _schema_aliases(tree: ast.Module) -> dict[str, str]:
    """Local name -> schema module (`from mrnc_eval.schema import slam as S` gives S -> slam)."""
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "mrnc_eval.schema":
            out.update({a.asname or a.name: a.name for a in node.names})
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("mrnc_eval.schema."):
            module = node.module.rsplit(".", 1)[1]
            out.update({a.asname or a.name: f"{module}.{a.name}" for a in node.names})
    return out


def schema_names(source: str) -> set[str]:
    """Schema names a module uses: "slam.APE_T", "control.side_series", "info.INFO"."""
    tree = ast.parse(source)
    aliases = _schema_aliases(tree)
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            used.add(f"{aliases[node.value.id]}.{node.attr}")
        elif isinstance(node, ast.Name) and "." in aliases.get(node.id, ""):
            used.add(aliases[node.id])
    return used


def _is_result_map(node: ast.expr) -> bool:
    name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
    return name in RESULT_MAPS


def literal_keys(source: str) -> list[str]:
    """Keys spelled out instead of named through the schema: `s["x"]`, `r.extra.get("x")`,
    `"x" in result.series`, f-string keys likewise."""
    out = []
    for node in ast.walk(ast.parse(source)):
        key = None
        if isinstance(node, ast.Subscript) and _is_result_map(node.value):
            key = node.slice
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
              and _is_result_map(node.func.value) and node.args):
            key = node.args[0]
        elif isinstance(node, ast.Compare) and any(isinstance(op, ast.In | ast.NotIn) for op in node.ops) \
                and _is_result_map(node.comparators[0]):
            key = node.left
        if isinstance(key, ast.Constant | ast.JoinedStr):
            out.append(f"{node.lineno}: {ast.unparse(key)}")
    return out


def _source(rel: str) -> str:
    return (PACKAGE / rel).read_text(encoding="utf-8")


def test_readers_name_result_keys_through_the_schema() -> None:
    found = {rel: hits for rel in READERS if (hits := literal_keys(_source(rel)))}
    assert not found, f"use mrnc_eval/schema/ names: {found}"


def test_every_key_a_reader_uses_is_one_a_command_writes() -> None:
    written = set().union(*(schema_names(_source(rel)) for rel in WRITERS))
    read = {rel: schema_names(_source(rel)) for rel in READERS}
    assert all(read.values()), f"a reader that names no schema key: {[r for r, n in read.items() if not n]}"
    unwritten = {rel: sorted(names - written) for rel, names in read.items() if names - written}
    assert not unwritten, f"read but written by no command: {unwritten}"


def test_the_writers_name_their_series_through_the_schema() -> None:
    for rel in WRITERS[:2]:  # the slam and control results' series and extra keys readers use
        names = schema_names(_source(rel))
        assert names, rel
    assert "control.side_series" in schema_names(_source("commands/control.py"))
    assert "slam.ape_err" in schema_names(_source("commands/slam.py"))


def test_the_checks_catch_a_planted_reader() -> None:
    """Negative controls: a figure reading a series nobody writes, and one spelling a key out."""
    reader = ("from mrnc_eval.schema import control as C\n"
              "def fig(s):\n"
              "    return s[C.side_series('raid', 'left', C.U_FB_RPM)], s[C.slip_ratio('raid')]\n")
    writer = ("from mrnc_eval.schema import control as K\n"
              "def add(result):\n"
              "    result.series[K.side_series('raid', 'left', K.U_FB_RPM)] = 1\n")
    assert schema_names(reader) - schema_names(writer) == {"control.slip_ratio"}
    assert sorted(literal_keys("def fig(r, s, ctrl):\n    if f'{ctrl}_left_v_ref' not in s:\n        return s['t']\n"
                        "    return r.extra.get('mode')\n")) == ["2: f'{ctrl}_left_v_ref'", "3: 't'", "4: 'mode'"]
