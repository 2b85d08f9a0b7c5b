"""Issue 26, the second reliability wave: each item's reproduction through the CLI (in-process,
`tests.reliability_cases.cli`) or the library, on small simulated logs. Each test failed on the
code before its fix (the commit message says how)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.reliability_cases import Run, cli, make_sim_log, one_line, run_folders


def _json(run: Run, meta: str | None = None) -> dict:
    """The first result of a verb's --json document (the one shape of every verb), or a meta entry."""
    body = json.loads(run.out)
    return body["meta"][meta] if meta else body["results"][0]


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
        for topic, t_rec, raw in lg.source.iterate(list(lg.source.channels)):
            msgtype = lg.source.channels[topic].msgtype
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
        "rpe": cli("rpe", f"{log}:/ground_truth", f"{log}:/odom{HOSTILE}", "-v"),
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


# ------------------------------------------------------------------ 4: chunk CRCs


def _cloud_chunk(path: Path) -> tuple[int, int]:
    """(offset, length) of the first chunk record holding a point cloud."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    cloud = next(cid for cid, ch in summary.channels.items() if ch.topic == "/ouster/points")
    ci = next(ci for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
              if cloud in ci.message_index_offsets)
    return ci.chunk_start_offset, ci.chunk_length


def _flip(path: Path, at: int) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 0x10
    path.write_bytes(bytes(data))


def test_04_simulated_logs_carry_chunk_crcs_and_a_flipped_byte_is_found(sim_log: Path, tmp_path: Path) -> None:
    from mrnc_eval.io.integrity import verify_chunks

    check = verify_chunks(sim_log)
    assert check.chunks > 1
    assert check.with_crc == check.chunks  # 0 of them before: rosbags writes none
    log = tmp_path / "flipped.mcap"
    shutil.copy(sim_log, log)
    shutil.copy(sim_log.with_name("s.gt.tum"), tmp_path / "flipped.gt.tum")
    offset, length = _cloud_chunk(log)
    _flip(log, offset + length - 200)  # inside the compressed records of a chunk with clouds
    info = cli("info", log, "--json")
    damaged = [f for f in _json(info)["findings"] if "damaged" in f["message"]] if info.code == 0 else []
    assert damaged or "damaged" in info.err, (info.code, info.err)  # said, as a finding or as the error
    if damaged:
        assert damaged[0]["level"] == "error"
        assert "/ouster/points" in damaged[0]["topic"]
    slam = cli("slam", log, "--out", tmp_path / "R", "--no-loop")
    assert slam.code == 4, slam.err
    assert one_line(slam)
    assert "damaged" in slam.err
    assert not run_folders(tmp_path / "R")


def test_04_a_log_without_crcs_says_so_in_info_and_the_result(sim_log: Path, tmp_path: Path) -> None:
    import struct

    from mrnc_eval.io.integrity import _CHUNK, _records

    log = tmp_path / "old.mcap"
    shutil.copy(sim_log, log)
    with log.open("r+b") as fh:  # as rosbags writes them: every chunk's CRC 0
        for offset in [off for op, off, _n in _records(fh) if op == _CHUNK]:
            fh.seek(offset + 9 + 24)
            fh.write(struct.pack("<I", 0))
    findings = _json(cli("info", log, "--json"))["findings"]
    assert any("carry no CRC" in f["message"] and f["level"] == "warning" for f in findings), findings
    assert not any("carry no CRC" in f["message"] for f in _json(cli("info", sim_log, "--json"))["findings"])
    r = cli("slam", log, "--out", tmp_path / "R", "--no-loop")
    assert r.code == 0, r.err
    warnings = json.loads((run_folders(tmp_path / "R")[0] / "result.json").read_text())["warnings"]
    assert any("carry no CRC" in w for w in warnings), warnings


# ------------------------------------------------------------------ 14: absolute log paths


def test_14_result_json_records_the_absolute_log_path(sim_log: Path, tmp_path: Path, monkeypatch) -> None:
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(sim_log, work / "s.mcap")
    shutil.copy(sim_log.with_name("s.gt.tum"), work / "s.gt.tum")
    monkeypatch.chdir(work)
    r = cli("control", "s.mcap", "--mode", "replay", "--out", "R")
    assert r.code == 0, r.err
    run = run_folders(work / "R")[0]
    assert json.loads((run / "result.json").read_text())["log_path"] == str(work / "s.mcap")
    monkeypatch.chdir(tmp_path)  # another folder: the log is still found
    e = cli("export", run, "--mcap", tmp_path / "e.mcap", "--with-log")
    assert e.code == 0, e.err


# ------------------------------------------------------------------ 5: gates on non-numbers


@pytest.mark.parametrize("stored", ["0.004", None, "inf"])
def test_05_a_gate_whose_metric_is_not_a_finite_number_fails(stored: object, slam_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(slam_run, run)
    body = json.loads((run / "result.json").read_text())
    for m in body["metrics"]:
        if m["name"] == "ape_rmse_m":
            m["value"] = stored  # text, null (a NaN), or "inf" (read back as infinity)
    (run / "result.json").write_text(json.dumps(body))
    r = cli("report", run, "--out", tmp_path / "rep", "--junit", tmp_path / "gates.xml")
    assert r.code == 1, r.err  # exit 0 before: the gate was "skipped"
    assert "APE RMSE" in r.err
    xml = (tmp_path / "gates.xml").read_text()
    assert "<skipped" not in xml.split("APE RMSE")[1].split("</testcase>")[0]


# ------------------------------------------------------------------ 6: every trajectory validated


def test_06_zero_quaternions_in_a_tum_file_or_an_api_trajectory_are_refused(sim_log: Path, tmp_path: Path) -> None:
    from mrnc_eval import api
    from mrnc_eval.errors import InputError
    from mrnc_eval.io.trajectory_files import read_tum

    gt = sim_log.with_name("s.gt.tum")
    rows = gt.read_text().splitlines()
    data = [k for k, ln in enumerate(rows) if ln.strip() and not ln.startswith("#")]
    zero = tmp_path / "zero_q.tum"
    zero.write_text("\n".join(" ".join([*ln.split()[:4], "0", "0", "0", "0"]) if k in data else ln
                              for k, ln in enumerate(rows)) + "\n")
    r = cli("ape", gt, zero, "--relation", "angle_deg")
    assert r.code == 4, r.out  # exit 0 with 0.000 deg before
    assert one_line(r)
    assert "quaternion" in r.err
    assert f"line {data[0] + 1}" in r.err
    assert r.out == ""
    traj = read_tum(gt)
    traj.quat_xyzw[:] = 0.0
    with pytest.raises(InputError, match="quaternion"):
        api.ape(gt, traj, relation="angle_deg")
    assert api.ape(gt, gt, relation="angle_deg").stats["rmse"] == pytest.approx(0.0, abs=1e-9)  # a valid one passes


# ------------------------------------------------------------------ 7, 8: table rows and "not run"


def test_07_08_table_has_one_row_per_log_path_and_says_not_run(sim_log: Path, tmp_path: Path) -> None:
    logs = []
    for day in ("day1", "day2"):
        (tmp_path / day).mkdir()
        logs.append(shutil.copy(sim_log, tmp_path / day / "run.mcap"))
        shutil.copy(sim_log.with_name("s.gt.tum"), tmp_path / day / "run.gt.tum")
    out = tmp_path / "R"
    r = cli("slam", *logs, "--out", out, "--no-loop")
    assert r.code == 0, r.err
    table = _json(cli("table", out, "--json"), "table")
    assert table["row_labels"] == ["day1/run", "day2/run", "Mean"]  # one merged row before
    assert all(isinstance(row[0], float) for row in table["cells"][:2])
    # a second method run on day1 only: day2's cell is "not run", not "Failed"
    day1 = next(p for p in run_folders(out) if json.loads((p / "result.json").read_text())["log_path"].endswith(
        "day1/run.mcap"))
    other = out / "other-run"
    shutil.copytree(day1, other)
    body = json.loads((other / "result.json").read_text())
    body["extra"]["method"] = "other"
    (other / "result.json").write_text(json.dumps(body))
    table = _json(cli("table", out, "--json"), "table")
    col = table["column_labels"].index("other")
    assert table["cells"][0][col] == pytest.approx(table["cells"][0][table["column_labels"].index("lio")])
    assert table["cells"][1][col] == "not run"  # "Failed" before
    assert not any(n.startswith("day2/run / other: Failed") for n in table["notes"])


# ------------------------------------------------------------------ 9: compare verdicts


def _edited_copy(run: Path, dst: Path, values: dict[str, object], log_path: str | None = None) -> Path:
    shutil.copytree(run, dst)
    body = json.loads((dst / "result.json").read_text())
    for m in body["metrics"]:
        if m["name"] in values:
            m["value"] = values[m["name"]]
    if log_path is not None:
        body["log_path"] = log_path
    (dst / "result.json").write_text(json.dumps(body))
    return dst


NO_VERDICT = "\u2013"  # how an empty cell is shown


def _verdicts(markdown: str) -> dict[str, str]:
    rows = [ln.split("|") for ln in markdown.splitlines() if ln.startswith("| slam/")]
    return {cells[1].strip(): cells[-2].strip() for cells in rows}


def test_09_compare_verdicts_only_where_the_direction_is_known(slam_run: Path, tmp_path: Path) -> None:
    a = _edited_copy(slam_run, tmp_path / "a", {"ape_n": 100, "loop_closures": 2, "ape_rmse_m": 0.01,
                                                "end_drift_m": "inf", "rtf": 2.0})
    b = _edited_copy(slam_run, tmp_path / "b", {"ape_n": 150, "loop_closures": 1, "ape_rmse_m": 0.02,
                                                "end_drift_m": "inf", "rtf": 3.0})
    r = cli("compare", a, b, "--format", "markdown")
    assert r.code == 0, r.err
    verdicts = _verdicts(r.out)
    assert verdicts["slam/ape/ape_n"] == NO_VERDICT  # more matched poses: "worse" before
    assert verdicts["slam/loop_closures"] == NO_VERDICT  # fewer loop closures: "better" before
    assert verdicts["slam/ape/ape_rmse_m"] == "worse"  # the known directions still judged
    assert verdicts["slam/rtf"] == "better"
    assert verdicts["slam/ape/end_drift_m"] == "same"  # inf = inf is no change
    assert "different" not in r.err
    changed = _verdicts(cli("compare", a, b, "--format", "markdown", "--changed-only").out)
    assert "slam/ape/end_drift_m" not in changed
    assert "slam/ape/ape_rmse_m" in changed


def test_09_compare_warns_on_different_logs_or_kinds(slam_run: Path, tmp_path: Path) -> None:
    other = _edited_copy(slam_run, tmp_path / "other", {}, log_path="/data/another.mcap")
    r = cli("compare", slam_run, other, "--format", "markdown")
    assert r.code == 0
    assert "different logs" in r.err
    assert "different logs" in r.out  # in the table's notes too (--out files keep it)
    control = tmp_path / "C"
    assert cli("control", "--mode", "simulate", "--controllers", "pid", "--out", control).code == 0
    r = cli("compare", slam_run, run_folders(control)[0], "--format", "markdown")
    assert "different kinds" in r.err


# ------------------------------------------------------------------ 10: dropped inputs counted


def _rewrite(src: Path, dst: Path, *, keep=None, edit=None, fmt: str = "mcap") -> Path:
    """Copy a log message by message, leaving out messages (keep(topic, k) False) or editing them."""
    from mrnc_eval.io import open_log
    from mrnc_eval.io.ground_truth import gt_tum_path
    from mrnc_eval.io.writers import LogWriter

    counts: dict[str, int] = {}
    with open_log(src) as lg, LogWriter(dst, fmt) as w:  # type: ignore[arg-type]
        for topic, t_rec, raw in lg.source.iterate(list(lg.source.channels)):
            msgtype = lg.source.channels[topic].msgtype
            k = counts.get(topic, 0)
            counts[topic] = k + 1
            if keep is not None and not keep(topic, k):
                continue
            if edit is not None and topic in edit:
                raw = w._serialize(edit[topic](lg.source.decode(raw, topic), k), msgtype)
            w._writer.write(w._conn(topic, msgtype, latched=topic == "/tf_static"), t_rec, bytes(raw))
    shutil.copy(gt_tum_path(src), gt_tum_path(dst))
    return dst


def _bad_sweeps(msg, k: int):
    import numpy as np

    if k == 3:
        msg.data = np.zeros_like(msg.data)  # all-zero points: none valid
    if k == 6:
        msg.data = np.full_like(msg.data, 0xFF)  # all NaN
    return msg


def _slam_result(log: Path, out: Path) -> dict:
    r = cli("slam", log, "--out", out, "--no-loop")
    assert r.code == 0, r.err
    return json.loads((run_folders(out)[0] / "result.json").read_text())


def test_10_dropped_sweeps_and_a_slow_imu_are_counted(sim_log: Path, tmp_path: Path) -> None:
    bad = _slam_result(_rewrite(sim_log, tmp_path / "bad.mcap", edit={"/ouster/points": _bad_sweeps}),
                       tmp_path / "R1")
    metrics = {m["name"]: m["value"] for m in bad["metrics"]}
    assert metrics["sweeps_empty"] == 2  # nothing in the result before
    assert any("2 of 10 sweep(s) had no valid point" in w for w in bad["warnings"]), bad["warnings"]
    good = {m["name"]: m["value"] for m in _slam_result(sim_log, tmp_path / "R2")["metrics"]}
    assert "sweeps_empty" not in good
    assert good["sweeps_without_imu"] == 0  # negative control: a 100 Hz IMU covers every sweep
    slow = _slam_result(_rewrite(sim_log, tmp_path / "slow.mcap",
                                 keep=lambda topic, k: topic != "/ouster/imu" or k % 50 == 0), tmp_path / "R3")
    metrics = {m["name"]: m["value"] for m in slow["metrics"]}
    assert metrics["sweeps_without_imu"] >= 4  # a 2 Hz IMU under 5 Hz mapping
    assert any("no IMU sample since the previous" in w and "2.0 Hz" in w for w in slow["warnings"]), slow["warnings"]


def test_10_sqlite_messages_of_a_missing_topic_id_are_counted(sim_log: Path, tmp_path: Path) -> None:
    import sqlite3

    bag = _rewrite(sim_log, tmp_path / "b.db3", fmt="db3")
    db = sqlite3.connect(bag)
    with db:
        total = db.execute("SELECT COUNT(*) FROM messages").fetchone()[0]
        lost = db.execute("UPDATE messages SET topic_id = 999 WHERE id % 7 = 0").rowcount
    db.close()
    findings = _json(cli("info", bag, "--json"))["findings"]
    line = f"{lost} of {total} messages"
    assert any(line in f["message"] and f["level"] == "warning" for f in findings), findings
    result = _slam_result(bag, tmp_path / "R")
    assert any(line in w for w in result["warnings"]), result["warnings"]


# ------------------------------------------------------------------ 11: ranges declared, checked before work

OUT_OF_RANGE = ["control.sweep.duration_s=-100", "slam.imu.acc_noise=0", "control.raid.beta=0",
                "control.raid.beta=-1", "slam.matching.max_iterations=0", "gates.ape_rmse_max_m=-1",
                "control.sweep.delay_s=[0.08, 0.02]", "nightly.scheduler_timeout_s=-5",
                "control.sweep.runs=1000000000000000000000000000000"]


@pytest.mark.parametrize("override", OUT_OF_RANGE)
def test_11_out_of_range_parameters_are_refused_before_any_work(override: str, sim_log: Path, tmp_path: Path) -> None:
    r = cli("config", "--set", override)
    assert r.code == 2, (override, r.out[-200:])  # accepted (0) or exit 5 later, before
    assert one_line(r)
    assert override.split("=")[0] in r.err
    if override.startswith("slam."):
        run = cli("slam", sim_log, "--out", tmp_path / "R", "--set", override)
        assert run.code == 2
        assert not (tmp_path / "R").exists()  # refused before the work, not after it


def test_11_every_new_parameter_declares_its_range() -> None:
    """Ranges are declared where the parameter is (params.param). tests/guessed_ranges.txt lists the
    parameters whose range is still guessed from the name; a parameter not on it must declare one,
    and one that declares it must leave the list, so the list can only shrink."""
    from dataclasses import fields, is_dataclass

    from mrnc_eval.config import Config

    def leaves(cfg, where=""):
        for f in fields(cfg):
            value, dotted = getattr(cfg, f.name), f"{where}.{f.name}" if where else f.name
            yield from leaves(value, dotted) if is_dataclass(value) else [(dotted, f, value)]

    guessed = {k for k, f, v in leaves(Config()) if isinstance(v, (int, float)) and not isinstance(v, bool)
               and not f.metadata.get("bounds") and not f.metadata.get("check")}
    listed = {ln.strip() for ln in (Path(__file__).with_name("guessed_ranges.txt")).read_text().splitlines()
              if ln.strip() and not ln.startswith("#")}
    assert not guessed - listed, f"declare a range (param(..., ge=/gt=/le=/lt=)) for {sorted(guessed - listed)}"
    assert not listed - guessed, f"declared now: remove from tests/guessed_ranges.txt {sorted(listed - guessed)}"
    assert not [k for k in guessed if k.split(".")[0] in ("gates", "nightly", "evaluation", "io")]
    assert len(listed) <= 245  # 248 before issue 26


def test_11_damaged_history_and_series_files_are_input_errors(slam_run: Path, tmp_path: Path) -> None:
    root = tmp_path / "N"
    root.mkdir()
    (root / "history.sqlite").write_bytes(b"SQLite format 3\x00" + b"\x13" * 2000)  # a damaged database
    r = cli("compare", "--history", root, "--nights", "2026-01-01", "2026-01-02")
    assert r.code == 4, r.err  # exit 5, "internal error", no file named, before
    assert one_line(r)
    assert "history.sqlite" in r.err
    run = tmp_path / "run"
    shutil.copytree(slam_run, run)
    data = bytearray((run / "series.npz").read_bytes())
    (run / "series.npz").write_bytes(bytes(data[: len(data) // 2]))  # cut in half
    r = cli("report", run, "--out", tmp_path / "rep")
    assert r.code == 4, r.err
    assert "series.npz" in r.err
    assert not (tmp_path / "rep").exists()


# ------------------------------------------------------------------ 12: messages


def test_12_write_errors_name_the_target_and_the_reason(slam_run: Path, tmp_path: Path) -> None:
    import errno
    from unittest import mock

    full = OSError(errno.ENOSPC, "No space left on device")
    with mock.patch("numpy.savez_compressed", side_effect=full):
        r = cli("control", "--mode", "simulate", "--controllers", "pid", "--out", tmp_path / "R")
    assert r.code == 4
    assert one_line(r)
    assert "no space left on device" in r.err
    assert str(tmp_path / "R") in r.err
    assert ".partial" not in r.err  # the hidden temporary folder, before
    real_write = Path.write_text

    def write_text(self: Path, *args, **kwargs):
        if self.name.startswith(".report.html."):
            raise OSError(errno.ENOSPC, "No space left on device", str(self))
        return real_write(self, *args, **kwargs)

    with mock.patch.object(Path, "write_text", write_text):
        r = cli("report", slam_run, "--out", tmp_path / "rep")
    assert r.code == 4
    assert f"{tmp_path / 'rep' / 'report.html'}: cannot write: no space left on device" in r.err
    assert not any(p.name.startswith(".report.html.") for p in (tmp_path / "rep").iterdir())


def test_12_sweep_runs_from_the_configuration_is_named_as_such(tmp_path: Path) -> None:
    from mrnc_eval.commands.control_sweep import run_sweep_result
    from mrnc_eval.config import load_config
    from mrnc_eval.errors import UsageError

    cfg = tmp_path / "c.yaml"
    cfg.write_text("control:\n  sweep:\n    runs: 0\n")
    r = cli("control", "--mode", "sweep", "--config", cfg, "--out", tmp_path / "R")
    assert r.code == 2
    assert "control.sweep.runs" in r.err
    assert "--runs" not in r.err
    with pytest.raises(UsageError, match="--runs 0"):
        run_sweep_result(load_config(), ("pid",), tmp_path / "S", runs=0, seed=None)


def test_12_a_cut_ros1_bag_gets_the_reindex_hint(sim_log: Path, tmp_path: Path) -> None:
    bag = _rewrite(sim_log, tmp_path / "b.bag", fmt="bag")
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) - 3000])  # the recorder stopped before writing the index
    r = cli("info", bag)
    assert r.code == 4
    assert one_line(r)
    assert "rosbag reindex" in r.err


def test_12_info_agrees_with_itself_on_duplicate_sweep_stamps(sim_log: Path, tmp_path: Path) -> None:
    previous: list[tuple[int, int]] = []

    def duplicate(msg, k: int):
        if k == 4:
            msg.header.stamp.sec, msg.header.stamp.nanosec = previous[-1]
        previous.append((msg.header.stamp.sec, msg.header.stamp.nanosec))
        return msg

    log = _rewrite(sim_log, tmp_path / "dup.mcap", edit={"/ouster/points": duplicate})
    info = _json(cli("info", log, "--json"))
    messages = [f["message"] for f in info["findings"] if f["topic"] == "/ouster/points"]
    assert any("1 duplicate header stamps (dropped" in m for m in messages)
    assert any(m.startswith("9 sweeps (10 recorded, 1 with a duplicate stamp dropped)") for m in messages), messages
    assert any("IMU covers 9 of 9 sweeps" in m for m in messages), messages  # "10 sweeps", "10 of 10" before
    assert info["lidar"]["sweeps"] == 9


# ------------------------------------------------------------------ 13: full tables off a terminal


def test_13_rich_tables_are_not_cut_off_a_terminal(slam_run: Path, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.delenv("COLUMNS", raising=False)
    control = cli("control", "--mode", "simulate", "--controllers", "raid,pid", "--out", tmp_path / "R")
    assert control.code in (0, 1), control.err
    assert "…" not in control.out  # "Sett…", "0.0…" at rich's assumed 80 columns, before
    assert "Settling" in control.out or "settling" in control.out
    assert max(len(ln) for ln in control.out.splitlines()) > 80  # the table kept its width
    compare = cli("compare", slam_run, slam_run)
    assert compare.code == 0
    assert "…" not in compare.out
    assert "slam/timing/ms_per_sweep_matching" in compare.out


# ------------------------------------------------------------------ 15: ape on a result folder, -v/-vv


def test_15_ape_on_a_result_folder_uses_what_slam_reports_and_says_so(sim_log: Path, slam_run: Path) -> None:
    result = json.loads((slam_run / "result.json").read_text())
    online = next(m["value"] for m in result["metrics"] if m["name"] == "ape_online_rmse_m")
    r = cli("ape", sim_log.with_name("s.gt.tum"), slam_run, "--json", "--max-diff", "0.02", "--align", "se3")
    assert r.code == 0, r.err
    assert _json(r)["stats"]["rmse"] == pytest.approx(online, rel=1e-6)  # the smoothed one before
    assert "trajectory_online.tum" in r.err
    assert "online" in r.err


def test_15_verbose_flags_print_progress(sim_log: Path, tmp_path: Path) -> None:
    quiet = cli("info", sim_log)
    assert "INFO" not in quiet.err
    for argv in (["info", sim_log], ["ape", f"{sim_log}:/ground_truth", f"{sim_log}:/wheel_odom"],
                 ["slam", sim_log, "--out", tmp_path / "R", "--no-loop"]):
        r = cli(*argv, "-v")
        assert r.code == 0, r.err
        assert any(ln.startswith("INFO mrnc_eval") for ln in r.err.splitlines()), (argv[0], r.err)  # nothing before
        assert "DEBUG" not in r.err
    r = cli("slam", sim_log, "--out", tmp_path / "R", "--no-loop", "-vv")
    debug = [ln for ln in r.err.splitlines() if ln.startswith("DEBUG")]
    assert debug
    assert all(ln.startswith("DEBUG mrnc_eval") for ln in debug)  # our stages, not numba's compiler trace


# ------------------------------------------------------------------ 16: typed API errors


def test_16_the_api_raises_the_clis_typed_errors_with_its_messages(sim_log: Path, tmp_path: Path) -> None:
    from mrnc_eval import api
    from mrnc_eval.errors import MrncError

    gt = sim_log.with_name("s.gt.tum")
    zero = tmp_path / "zero.tum"
    zero.write_text("1.0 0 0 0 0 0 0 0\n2.0 1 0 0 0 0 0 0\n")
    pairs = [  # (CLI argv, the same request through the API)
        (["ape", gt, zero], lambda: api.ape(gt, zero)),
        (["ape", gt, tmp_path / "missing.tum"], lambda: api.ape(gt, tmp_path / "missing.tum")),
        (["ape", gt, gt, "--offset", "abc"], lambda: api.ape(gt, gt, offset="abc")),
        (["control", "--mode", "simulate", "--controllers", "nope", "--out", tmp_path / "R"],
         lambda: api.run_control(None, tmp_path / "A", mode="simulate", controllers=["nope"])),
        (["config", "--set", "slam.nope=1"], lambda: api.config(None, ["slam.nope=1"])),
    ]
    for argv, call in pairs:
        r = cli(*argv)
        with pytest.raises(MrncError) as caught:  # ValueError / UFuncTypeError for the last three before
            call()
        assert caught.value.exit_code == r.code, (argv, r.err)
        assert str(caught.value) in r.err, (argv, r.err, str(caught.value))
    for call in (lambda: api.ape(gt, gt, bogus=1), lambda: api.ape(gt, gt, sync="nope"),
                 lambda: api.rpe(gt, gt, pairs_from="nope")):
        with pytest.raises(MrncError):  # TypeError / ValueError before
            call()
