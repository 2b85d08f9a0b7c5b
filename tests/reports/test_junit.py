"""`nightly --junit` and `report --junit`: the XML parsed as a CI system reads it."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from mrnc_eval.commands.log_job import Analysis
from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.results import Metric, RunResult, write_result
from tests.reports.conftest import write_imu_log

GATES = ["APE RMSE (lio)", "Funnel violations", "Saturation ratio", "Safety stops"]  # the same for every log
APE_M = {"good": 0.02, "drifty": 0.35}  # the default APE gate is 0.10 m
WALL_S = {"good": 1.25, "drifty": 2.5}  # the SLAM run's real time, s
XSD = Path(__file__).resolve().parents[1] / "data" / "junit-10.xsd"  # Jenkins xunit-plugin's schema (source in it)


def gate_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """SLAM with a chosen APE for "good" and "drifty"; a control replay only for "good" (3 funnel
    violations); "noctl" has SLAM without ground truth and no control. The log is opened for real,
    so a corrupt file fails as it would in the real analysis."""
    from mrnc_eval.commands import info
    from mrnc_eval.reports.render import evaluate_gates

    summary = info.run(log_path, cfg).to_json()
    ch = config_hash(cfg)
    slam = RunResult(kind="slam", log_path=str(log_path), log_id=log_id, config_hash=ch,
                     extra={"wall_total_s": WALL_S[log_id]} if log_id in WALL_S else {})
    if log_id in APE_M:
        slam.metrics.append(Metric(name="ape_rmse_m", value=APE_M[log_id], unit="m", group="slam/ape"))
    else:
        slam.warnings.append("no ground truth (topic or <log>.gt.tum): APE not computed")
    results = [RunResult(kind="info", log_path=str(log_path), log_id=log_id, extra={"info": summary},
                         config_hash=ch), slam]
    if log_id == "good":
        results.append(RunResult(kind="control", log_path=str(log_path), log_id=log_id, config_hash=ch,
                                 extra={"wall_s": 0.75}, metrics=[
            Metric(name="funnel_violations", value=3, unit="", group="control/recorded/left"),
            Metric(name="saturation_ratio", value=0.05, unit="", group="control/recorded/left"),
            Metric(name="safety_stops", value=0, unit="", group="control/recorded/left")]))
    else:
        results[0].warnings.append("control replay skipped: the log has no path and no wheel_speeds topic")
    for r in results:
        write_result(r, work_dir / r.kind, dump_config(cfg))
    return Analysis(metrics=[(f"{m.group}/{m.name}", m.value, m.unit) for r in results for m in r.metrics],
                    gates_failed=[g.label for g in evaluate_gates(results, cfg.gates) if g.status == "fail"])


def run_night_with_junit(tmp_path: Path) -> tuple[int, ET.Element, Path]:
    from mrnc_eval.commands import nightly
    from mrnc_eval.errors import MrncError

    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("good", "drifty", "noctl"):
        write_imu_log(logs / f"{name}.mcap", 30)
    (logs / "bad<&>\x1b.mcap").write_bytes(b"\x89MCAP0\r\n garbage ]]> <x>")
    junit = tmp_path / "ci" / "gates.xml"
    try:
        nightly.main(logs, Config(), out=tmp_path / "reports", jobs=1, scheduler=None, since=None, gates=None,
                     date="2026-11-21", pdf=False, analysis=f"{__name__}:gate_analysis", junit=junit)
        code = 0
    except MrncError as err:
        code = err.exit_code
    return code, ET.parse(junit).getroot(), junit


@pytest.fixture(scope="module")
def night(tmp_path_factory) -> tuple[int, ET.Element, Path]:
    return run_night_with_junit(tmp_path_factory.mktemp("junit_night"))


def cases_of(root: ET.Element) -> dict[tuple[str, str], ET.Element]:
    return {(suite.get("name"), case.get("name")): case for suite in root.iter("testsuite")
            for case in suite.iter("testcase")}


def test_nightly_junit_has_one_case_per_gate_per_log(night) -> None:
    code, root, _path = night
    assert code == 3  # a log failed
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert len(suites) == 4
    assert all([c.get("name") for c in s.findall("testcase")] == GATES for s in suites)
    assert int(root.get("tests")) == 16
    cases = cases_of(root)
    assert len(cases) == 16
    ape_fail = cases[("drifty", "APE RMSE (lio)")].find("failure")
    assert ape_fail is not None
    assert "0.350 m" in ape_fail.get("message")
    assert "0.1 m" in ape_fail.get("message")
    assert cases[("good", "APE RMSE (lio)")].find("failure") is None
    assert cases[("good", "APE RMSE (lio)")].find("skipped") is None
    funnel = cases[("good", "Funnel violations")].find("failure")
    assert funnel is not None
    assert "measured 3" in funnel.get("message")
    assert "limit 0" in funnel.get("message")
    assert int(root.get("failures")) == 2


def test_failed_log_is_an_error_and_unmeasured_gates_are_skipped_with_reason(night) -> None:
    _code, root, _path = night
    cases = cases_of(root)
    bad = next(s for s in root.findall("testsuite") if s.get("name").startswith("bad"))
    assert len(bad.findall("testcase")) == 4
    for case in bad.findall("testcase"):
        error = case.find("error")
        assert error is not None
        assert case.find("failure") is None
        assert case.find("skipped") is None
        assert "MCAP" in error.get("message") or "mcap" in error.get("message")
    path_prop = bad.find("properties/property[@name='log_path']").get("value")
    assert "bad<&>\\x1b.mcap" in path_prop  # escaped, still readable
    skipped = cases[("noctl", "APE RMSE (lio)")].find("skipped")
    assert skipped is not None
    assert "ground truth" in skipped.get("message")
    control_skip = cases[("noctl", "Safety stops")].find("skipped")
    assert "control replay skipped" in control_skip.get("message")
    assert int(root.get("errors")) == 4
    skipped = {s.get("name"): int(s.get("skipped")) for s in root.findall("testsuite")}
    assert sum(skipped.values()) == 3 + 4  # drifty: 3 control gates; noctl: all 4 (counted per suite)


def test_report_junit_from_result_directories(tmp_path: Path) -> None:
    from mrnc_eval.cli import main

    log = write_imu_log(tmp_path / "drifty.mcap", 30)
    gate_analysis(log, Config(), tmp_path / "runs", "drifty", False)
    junit = tmp_path / "report.xml"
    assert main(["report", str(tmp_path / "runs"), "--junit", str(junit)]) == 1  # the APE gate fails: exit 1
    root = ET.parse(junit).getroot()
    assert validate_against_junit10(junit) == []
    (suite,) = root.findall("testsuite")
    assert suite.get("failures") == "1"
    assert suite.get("skipped") == "3"


def validate_against_junit10(path: Path) -> list[str]:
    """Schema errors of `path` against junit-10.xsd (lxml; a test-only dependency)."""
    from tests.needs import need_module

    etree = need_module("lxml.etree", "lxml is not installed (pip install 'mrnc-eval[test]'): JUnit schema check")
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    ok = schema.validate(etree.parse(str(path)))
    return [] if ok else [str(e) for e in schema.error_log]


def test_nightly_junit_validates_against_jenkins_junit10_xsd(night) -> None:
    _code, root, path = night[0], night[1], night[2]
    assert validate_against_junit10(path) == []
    assert root.get("skipped") is None  # not allowed on <testsuites> by junit-10.xsd


def test_the_schema_check_can_fail(tmp_path: Path) -> None:
    """Negative control: the old output (skipped on <testsuites>) and a bad time are refused."""
    bad = tmp_path / "bad.xml"
    bad.write_text('<testsuites skipped="1"><testsuite name="a" tests="1" failures="0" errors="0" time="1e-3">'
                   '<testcase name="g"/></testsuite></testsuites>', encoding="utf-8")
    errors = validate_against_junit10(bad)
    assert any("skipped" in e for e in errors)
    assert any("time" in e for e in errors)


def test_gate_names_are_equal_for_a_passing_and_a_failing_log(night) -> None:
    _code, root = night[0], night[1]
    names = {s.get("name"): [c.get("name") for c in s.findall("testcase")] for s in root.findall("testsuite")}
    bad = next(k for k in names if k.startswith("bad"))
    assert names["good"] == names["drifty"] == names["noctl"] == names[bad] == GATES


def test_suites_carry_timestamp_hostname_and_real_times(night) -> None:
    import datetime as dt
    import socket

    _code, root = night[0], night[1]
    for suite in root.findall("testsuite"):
        assert suite.get("hostname") == socket.gethostname()
        stamp = dt.datetime.fromisoformat(suite.get("timestamp"))
        assert abs((dt.datetime.now() - stamp).total_seconds()) < 3 * 3600 + 24 * 3600  # UTC, today-ish
    cases = cases_of(root)
    assert float(cases[("good", "APE RMSE (lio)")].get("time")) == pytest.approx(WALL_S["good"])
    assert float(cases[("drifty", "APE RMSE (lio)")].get("time")) == pytest.approx(WALL_S["drifty"])
    assert float(cases[("good", "Safety stops")].get("time")) == pytest.approx(0.75)
    good = next(s for s in root.findall("testsuite") if s.get("name") == "good")
    assert float(good.get("time")) == pytest.approx(WALL_S["good"] + 0.75)
    assert float(root.get("time")) == pytest.approx(WALL_S["good"] + 0.75 + WALL_S["drifty"])
