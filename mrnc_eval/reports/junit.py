"""JUnit XML of the metric gates, for CI systems (Jenkins, GitLab, GitHub test reporters).

Structure as they read it (valid against Jenkins' junit-10.xsd, checked in a test):
<testsuites> holding one <testsuite> per log (timestamp, hostname, real time), holding one
<testcase> per gate, named the same whether the log passed, failed or could not run. A failed
gate is a <failure> with the measured value and the limit; a log that could not be evaluated
makes every gate an <error> (never a pass); a gate that was not measured is <skipped> with the
reason. Text from logs (ids, paths, error messages) goes
through ElementTree's escaping, and characters XML 1.0 cannot carry at all (control
characters such as ESC) are replaced by their escaped form first."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from mrnc_eval.evaluation.config import GatesConfig
from mrnc_eval.outputs import write_output
from mrnc_eval.reports.gates import Gate, evaluate_gates
from mrnc_eval.results import RunResult

Status = Literal["pass", "fail", "skipped", "error"]
_NOT_XML = re.compile("[^\u0009\u000a\u000d\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")
GATE_KIND = {"APE RMSE": "slam"}  # the other gates judge the control result
SKIP_HINTS = {"slam": ("APE", "ground truth"), "control": ("control",)}


def xml_text(text: str) -> str:
    """Text XML 1.0 can carry: each forbidden character as its Python escape (\\x1b)."""
    return _NOT_XML.sub(lambda m: repr(m.group())[1:-1], text)


@dataclass(frozen=True)
class GateCase:
    gate: str
    status: Status
    value: str = ""
    limit: str = ""
    message: str = ""  # reason of a skip, error text
    time_s: float = 0.0  # real time spent producing what the gate judges


@dataclass(frozen=True)
class LogSuite:
    log_id: str
    log_path: str
    cases: list[GateCase] = field(default_factory=list)
    timestamp: str = ""  # ISO 8601 (UTC, no zone suffix, as the schema's consumers expect) of the results
    time_s: float = 0.0  # real time of the log's analysis


def _skip_reason(gate: str, results: Sequence[RunResult]) -> str:
    kind = GATE_KIND.get(gate.split(" (")[0], "control")  # "APE RMSE (lio)": one card per SLAM method
    if not any(r.kind == kind for r in results):
        said = [w for r in results for w in r.warnings if kind in w.lower()]
        return f"not measured: no {kind} result" + (f" ({said[0]})" if said else "")
    said = [w for r in results if r.kind == kind for w in r.warnings if any(h in w for h in SKIP_HINTS[kind])]
    return "not measured" + (f": {said[0]}" if said else f": the {kind} result has no value for this gate")


def stable_names(label: str, methods: Sequence[str]) -> list[str]:
    """A gate's JUnit name, the same whether the log passed, failed or could not run: the APE
    gate is named by SLAM method ("APE RMSE (lio)") also when no SLAM result says which."""
    if label == "APE RMSE" and methods:
        return [f"APE RMSE ({m})" for m in methods]
    return [label]


def _gate_time(label: str, results: Sequence[RunResult]) -> float:
    """Real seconds of the results a gate judges (slam: wall_total_s of that method; control: wall_s)."""
    kind = GATE_KIND.get(label.split(" (")[0], "control")
    method = label[label.find("(") + 1:-1] if kind == "slam" and label.endswith(")") else None
    total = 0.0
    for r in results:
        if r.kind != kind or (method is not None and r.extra.get("method", method) != method):
            continue
        wall = r.extra.get("wall_total_s", r.extra.get("wall_s", 0.0))
        total += float(wall) if isinstance(wall, (int, float)) else 0.0
    return total


def _timestamp(results: Sequence[RunResult]) -> str:
    stamps = sorted(r.created_utc for r in results if r.created_utc)
    return stamps[0].removesuffix("Z") if stamps else _now()


def _now() -> str:
    import datetime as dt

    return dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")


def suite_of_results(log_id: str, log_path: str, results: Sequence[RunResult], gates: GatesConfig,
                     methods: Sequence[str] = ("lio",)) -> LogSuite:
    """The gate cards of a log's results (the report's evaluate_gates) as test cases, named stably."""
    cases = []
    for g in evaluate_gates(list(results), gates):
        for name in stable_names(g.label, methods):
            t = _gate_time(name, results)
            if g.status == "na":
                cases.append(GateCase(name, "skipped", g.value, g.limit, _skip_reason(g.label, results), t))
            else:
                cases.append(GateCase(name, "pass" if g.status == "pass" else "fail", g.value, g.limit, time_s=t))
    total = sum(float(w) for r in results for k in ("wall_total_s", "wall_s")
                if isinstance(w := r.extra.get(k), (int, float)) and (k == "wall_total_s" or r.kind != "slam"))
    return LogSuite(log_id, log_path, cases, timestamp=_timestamp(results), time_s=total)


def error_suite(log_id: str, log_path: str, error: str, gates: GatesConfig,
                methods: Sequence[str] = ("lio",)) -> LogSuite:
    """A log that could not be evaluated: every gate is an error carrying the reason."""
    labels: list[Gate] = evaluate_gates([], gates)
    return LogSuite(log_id, log_path, [GateCase(name, "error", "", g.limit, error or "log failed")
                                       for g in labels for name in stable_names(g.label, methods)],
                    timestamp=_now())


def _seconds(t: float) -> str:
    return f"{max(t, 0.0):.3f}"  # SUREFIRE_TIME: digits and a point, no exponent


def render_junit(suites: Sequence[LogSuite], name: str, hostname: str | None = None) -> str:
    """JUnit XML valid against Jenkins' junit-10.xsd: <testsuites> carries name, tests, failures,
    errors and time (no `skipped`: the schema has none there); each <testsuite> adds skipped,
    timestamp, hostname and its real time; each <testcase> its real time."""
    import socket

    def count(cases: Sequence[GateCase], status: Status) -> str:
        return str(sum(c.status == status for c in cases))

    host = xml_text(hostname if hostname is not None else socket.gethostname())
    everything = [c for s in suites for c in s.cases]
    root = ET.Element("testsuites", name=xml_text(name), tests=str(len(everything)),
                      failures=count(everything, "fail"), errors=count(everything, "error"),
                      time=_seconds(sum(s.time_s for s in suites)))
    for k, s in enumerate(suites):
        suite = ET.SubElement(root, "testsuite", id=str(k), name=xml_text(s.log_id), tests=str(len(s.cases)),
                              failures=count(s.cases, "fail"), errors=count(s.cases, "error"),
                              skipped=count(s.cases, "skipped"), time=_seconds(s.time_s),
                              timestamp=s.timestamp or _now(), hostname=host)
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="log_path", value=xml_text(s.log_path))
        for c in s.cases:
            case = ET.SubElement(suite, "testcase", name=c.gate, classname=f"mrnc_eval.gates.{xml_text(s.log_id)}",
                                 time=_seconds(c.time_s))
            if c.status == "fail":
                text = f"{c.gate}: measured {c.value}, limit {c.limit}"
                ET.SubElement(case, "failure", message=text, type="GateFailed").text = text
            elif c.status == "error":
                text = xml_text(c.message)
                ET.SubElement(case, "error", message=text, type="LogFailed").text = text
            elif c.status == "skipped":
                ET.SubElement(case, "skipped", message=xml_text(c.message))
            else:
                ET.SubElement(case, "system-out").text = f"measured {c.value}, limit {c.limit}"
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_junit(path: Path, suites: Sequence[LogSuite], name: str, *, force: bool = False) -> None:
    """The suites as one JUnit XML file, written atomically under the one overwrite rule
    (mrnc_eval/outputs.py)."""
    write_output(path, render_junit(suites, name), force=force)
