"""Issue 26, the second reliability wave: each item's reproduction through the CLI (in-process,
`tests.reliability_cases.cli`) or the library, on small simulated logs. Each test failed on the
code before its fix (the commit message says how)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.reliability_cases import Run, cli, make_sim_log, one_line, run_folders


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_sim_log(tmp_path_factory.mktemp("round2_sim"))


@pytest.fixture(scope="module")
def slam_run(sim_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("round2_runs")
    r = cli("slam", sim_log, "--out", out, "--no-loop")
    assert r.code == 0, r.err
    return run_folders(out)[0]


# ------------------------------------------------------------------ 1, 3: one overwrite rule


def test_01_export_force_never_replaces_an_input_of_the_run(slam_run: Path, tmp_path: Path) -> None:
    result = json.loads((slam_run / "result.json").read_text())
    log = Path(result["log_path"])
    before = log.read_bytes()
    r = cli("export", slam_run, "--mcap", log, "--force")
    assert r.code == 4, r.err
    assert one_line(r)
    assert "input" in r.err
    assert log.read_bytes() == before  # byte-identical
    gt = log.with_name(log.name.removesuffix(".mcap") + ".gt.tum")
    gt_mcap = tmp_path / "x.mcap"
    shutil.copy(gt, gt_mcap)  # a file of the user's with an .mcap name: not ours either
    assert cli("export", slam_run, "--mcap", gt_mcap, "--force").code == 4
    assert gt_mcap.read_bytes() == gt.read_bytes()


def _ape_args(log: Path) -> list[object]:
    return ["ape", f"{log}:/ground_truth", f"{log}:/wheel_odom"]


@pytest.mark.parametrize("verb", ["report", "table", "compare", "ape-table", "ape-plot", "export", "report-junit"])
def test_03_one_overwrite_rule_for_every_output(verb: str, sim_log: Path, slam_run: Path, tmp_path: Path) -> None:
    """An existing file of the user's: refused with exit 4, even with --force; a file this tool
    wrote: refused without --force, replaced with it."""
    suffix = {"report": "", "table": ".md", "compare": ".md", "ape-table": ".md", "ape-plot": ".svg",
              "export": ".mcap", "report-junit": ".xml"}[verb]
    target = tmp_path / ("out" + suffix)

    def run(force: bool) -> Run:
        extra = ["--force"] if force else []
        if verb == "report":
            return cli("report", slam_run, "--out", tmp_path / "rep", *extra)
        if verb == "report-junit":
            return cli("report", slam_run, "--out", tmp_path / "rep2", "--junit", target, *extra)
        if verb == "table":
            return cli("table", slam_run.parent, "--out", target, *extra)
        if verb == "compare":
            return cli("compare", slam_run, slam_run, "--out", target, *extra)
        if verb == "export":
            return cli("export", slam_run, "--mcap", target, *extra)
        flag = "--table" if verb == "ape-table" else "--plot"
        return cli(*_ape_args(sim_log), flag, target, *extra)

    if verb == "report":
        target = tmp_path / "rep" / "report.html"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text("the user's own file\n")
    for force in (False, True):
        r = run(force)
        assert r.code == 4, (force, r.err)
        assert one_line(r)
        assert target.read_text() == "the user's own file\n"
        assert str(target) in r.err
    target.unlink()
    first = run(False)
    assert first.code in (0, 1), first.err  # 1: a gate of the tiny run may fail; the file is written
    assert target.exists()
    again = run(False)
    assert again.code == 4
    assert "--force" in again.err
    forced = run(True)
    assert forced.code in (0, 1), forced.err


def test_03_api_run_slam_refuses_an_existing_result(sim_log: Path, slam_run: Path, tmp_path: Path) -> None:
    from mrnc_eval import api
    from mrnc_eval.errors import OutputError

    target = tmp_path / "run"
    shutil.copytree(slam_run, target)
    before = (target / "result.json").read_bytes()
    with pytest.raises(OutputError, match="already exists"):
        api.run_slam(sim_log, target, overrides=["slam.loop.enabled=false"])
    assert (target / "result.json").read_bytes() == before


# ------------------------------------------------------------------ 2: log text escaped everywhere

HOSTILE = "\x1b]0;owned\x07\x00\x1b[2J\rERROR forged"  # OSC title, NUL, clear screen, a forged line


def _hostile_log(src: Path, dst: Path) -> Path:
    """The sample log with its GNSS topic renamed to carry ESC, OSC and NUL, and a second wheel
    odometry topic under such a name (role choice then has to talk about it)."""
    from mrnc_eval.io import open_log
    from mrnc_eval.io.ground_truth import gt_tum_path
    from mrnc_eval.io.writers import LogWriter

    names = {"/gnss/fix": "/gnss" + HOSTILE, "/wheel_odom": "/wheel_odom"}
    with open_log(src) as lg, LogWriter(dst, "mcap") as w:
        for topic, t_rec, raw in lg._iterate(list(lg._channels)):
            msgtype = lg._channels[topic].msgtype
            w._writer.write(w._conn(names.get(topic, topic), msgtype, latched=topic == "/tf_static"), t_rec,
                            bytes(raw))
            if topic == "/wheel_odom":
                w._writer.write(w._conn("/odom" + HOSTILE, msgtype), t_rec, bytes(raw))
    shutil.copy(gt_tum_path(src), gt_tum_path(dst))
    return dst


def _control_bytes(text: str) -> list[str]:
    return sorted({repr(c) for c in text if (ord(c) < 32 and c not in "\n\t") or 0x7f <= ord(c) < 0xa0})


def test_02_no_raw_control_byte_from_any_verb(sim_log: Path, tmp_path: Path) -> None:
    log = _hostile_log(sim_log, tmp_path / "logs" / "h.mcap")
    out = tmp_path / "R"
    runs: dict[str, Run] = {
        "info": cli("info", log), "info --json": cli("info", log, "--json"),
        "slam": cli("slam", log, "--out", out, "--no-loop", "-v"),
        "control": cli("control", log, "--mode", "replay", "--out", out, "-v"),
        "ape": cli("ape", f"{log}:/ground_truth", f"{log}:/odom{HOSTILE}", "-v"),
    }
    run_dirs = run_folders(out)
    slam_dir = next(p for p in run_dirs if "slam" in p.name)
    runs["report"] = cli("report", slam_dir, "--out", tmp_path / "rep")
    runs["table"] = cli("table", out)
    runs["compare"] = cli("compare", *run_dirs[:2])
    runs["export --with-log"] = cli("export", slam_dir, "--mcap", tmp_path / "e.mcap", "--with-log")
    runs["nightly"] = cli("nightly", log.parent, "--out", tmp_path / "N", "--jobs", 1, "--no-pdf")
    leaks = {verb: _control_bytes(r.out + r.err) for verb, r in runs.items()}
    assert not any(leaks.values()), leaks
    assert runs["slam"].code == 0, runs["slam"].err
    assert "\\x1b" in runs["info"].out  # shown escaped, not dropped
