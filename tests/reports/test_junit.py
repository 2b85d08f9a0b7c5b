"""`nightly --junit` and `report --junit`: the XML parsed as a CI system reads it."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from mrnc_eval.commands.log_job import Analysis
from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.results import Metric, RunResult, write_result
from tests.reports.conftest import write_imu_log

GATES = ["APE RMSE", "Funnel violations", "Saturation ratio", "Safety stops"]
APE_M = {"good": 0.02, "drifty": 0.35}  # the default APE gate is 0.10 m


def gate_analysis(log_path: Path, cfg: Config, work_dir: Path, log_id: str, pdf: bool) -> Analysis:
    """SLAM with a chosen APE for "good" and "drifty"; a control replay only for "good" (3 funnel
    violations); "noctl" has SLAM without ground truth and no control. The log is opened for real,
    so a corrupt file fails as it would in the real analysis."""
    from mrnc_eval.commands import info
    from mrnc_eval.reports.render import evaluate_gates

    summary = info.run(log_path, cfg).to_json()
    ch = config_hash(cfg)
    slam = RunResult(kind="slam", log_path=str(log_path), log_id=log_id, config_hash=ch)
    if log_id in APE_M:
        slam.metrics.append(Metric(name="ape_rmse_m", value=APE_M[log_id], unit="m", group="slam/ape"))
    else:
        slam.warnings.append("no ground truth (topic or <log>.gt.tum): APE not computed")
    results = [RunResult(kind="info", log_path=str(log_path), log_id=log_id, extra={"info": summary},
                         config_hash=ch), slam]
    if log_id == "good":
        results.append(RunResult(kind="control", log_path=str(log_path), log_id=log_id, config_hash=ch, metrics=[
            Metric(name="funnel_violations", value=3, unit="", group="control/recorded/left"),
            Metric(name="saturation_ratio", value=0.05, unit="", group="control/recorded/left"),
            Metric(name="safety_stops", value=0, unit="", group="control/recorded/left")]))
    else:
        results[0].warnings.append("control replay skipped: the log has no path and no wheel_speeds topic")
    for r in results:
        write_result(r, work_dir / r.kind, dump_config(cfg))
    return Analysis(metrics=[(f"{m.group}/{m.name}", m.value, m.unit) for r in results for m in r.metrics],
                    gates_failed=[g.label for g in evaluate_gates(results, cfg.gates) if g.status == "fail"])


def run_night_with_junit(tmp_path: Path) -> tuple[int, ET.Element]:
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
    return code, ET.parse(junit).getroot()


@pytest.fixture(scope="module")
def night(tmp_path_factory) -> tuple[int, ET.Element]:
    return run_night_with_junit(tmp_path_factory.mktemp("junit_night"))


def cases_of(root: ET.Element) -> dict[tuple[str, str], ET.Element]:
    return {(suite.get("name"), case.get("name")): case for suite in root.iter("testsuite")
            for case in suite.iter("testcase")}


def test_nightly_junit_has_one_case_per_gate_per_log(night) -> None:
    code, root = night
    assert code == 3  # a log failed
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert len(suites) == 4
    assert all([c.get("name") for c in s.findall("testcase")] == GATES for s in suites)
    assert int(root.get("tests")) == 16
    cases = cases_of(root)
    assert len(cases) == 16
    ape_fail = cases[("drifty", "APE RMSE")].find("failure")
    assert ape_fail is not None
    assert "0.350 m" in ape_fail.get("message")
    assert "0.1 m" in ape_fail.get("message")
    assert cases[("good", "APE RMSE")].find("failure") is None
    assert cases[("good", "APE RMSE")].find("skipped") is None
    funnel = cases[("good", "Funnel violations")].find("failure")
    assert funnel is not None
    assert "measured 3" in funnel.get("message")
    assert "limit 0" in funnel.get("message")
    assert int(root.get("failures")) == 2


def test_failed_log_is_an_error_and_unmeasured_gates_are_skipped_with_reason(night) -> None:
    _code, root = night
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
    skipped = cases[("noctl", "APE RMSE")].find("skipped")
    assert skipped is not None
    assert "ground truth" in skipped.get("message")
    control_skip = cases[("noctl", "Safety stops")].find("skipped")
    assert "control replay skipped" in control_skip.get("message")
    assert int(root.get("errors")) == 4
    assert int(root.get("skipped")) == 3 + 4  # drifty: 3 control gates; noctl: all 4


def test_report_junit_from_result_directories(tmp_path: Path) -> None:
    from mrnc_eval.cli import main

    log = write_imu_log(tmp_path / "drifty.mcap", 30)
    gate_analysis(log, Config(), tmp_path / "runs", "drifty", False)
    junit = tmp_path / "report.xml"
    assert main(["report", str(tmp_path / "runs"), "--junit", str(junit)]) == 1  # the APE gate fails: exit 1
    root = ET.parse(junit).getroot()
    (suite,) = root.findall("testsuite")
    assert suite.get("failures") == "1"
    assert suite.get("skipped") == "3"
