"""JUnit XML of the metric gates, for CI systems (Jenkins, GitLab, GitHub test reporters).

Structure as they read it: <testsuites> holding one <testsuite> per log, holding one
<testcase> per gate. A failed gate is a <failure> with the measured value and the limit; a
log that could not be evaluated makes every gate an <error> (never a pass); a gate that was
not measured is <skipped> with the reason. Text from logs (ids, paths, error messages) goes
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
from mrnc_eval.reports.render import Gate, evaluate_gates
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


@dataclass(frozen=True)
class LogSuite:
    log_id: str
    log_path: str
    cases: list[GateCase] = field(default_factory=list)


def _skip_reason(gate: str, results: Sequence[RunResult]) -> str:
    kind = GATE_KIND.get(gate.split(" (")[0], "control")  # "APE RMSE (lio)": one card per SLAM method
    if not any(r.kind == kind for r in results):
        said = [w for r in results for w in r.warnings if kind in w.lower()]
        return f"not measured: no {kind} result" + (f" ({said[0]})" if said else "")
    said = [w for r in results if r.kind == kind for w in r.warnings if any(h in w for h in SKIP_HINTS[kind])]
    return "not measured" + (f": {said[0]}" if said else f": the {kind} result has no value for this gate")


def suite_of_results(log_id: str, log_path: str, results: Sequence[RunResult], gates: GatesConfig) -> LogSuite:
    """The gate cards of a log's results (the report's evaluate_gates) as test cases."""
    cases = []
    for g in evaluate_gates(list(results), gates):
        if g.status == "na":
            cases.append(GateCase(g.label, "skipped", g.value, g.limit, _skip_reason(g.label, results)))
        else:
            cases.append(GateCase(g.label, "pass" if g.status == "pass" else "fail", g.value, g.limit))
    return LogSuite(log_id, log_path, cases)


def error_suite(log_id: str, log_path: str, error: str, gates: GatesConfig) -> LogSuite:
    """A log that could not be evaluated: every gate is an error carrying the reason."""
    labels: list[Gate] = evaluate_gates([], gates)
    return LogSuite(log_id, log_path, [GateCase(g.label, "error", "", g.limit, error or "log failed")
                                       for g in labels])


def render_junit(suites: Sequence[LogSuite], name: str) -> str:
    def count(cases: Sequence[GateCase], status: Status) -> str:
        return str(sum(c.status == status for c in cases))

    everything = [c for s in suites for c in s.cases]
    root = ET.Element("testsuites", name=xml_text(name), tests=str(len(everything)),
                      failures=count(everything, "fail"), errors=count(everything, "error"),
                      skipped=count(everything, "skipped"), time="0")
    for k, s in enumerate(suites):
        suite = ET.SubElement(root, "testsuite", id=str(k), name=xml_text(s.log_id), tests=str(len(s.cases)),
                              failures=count(s.cases, "fail"), errors=count(s.cases, "error"),
                              skipped=count(s.cases, "skipped"), time="0")
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="log_path", value=xml_text(s.log_path))
        for c in s.cases:
            case = ET.SubElement(suite, "testcase", name=c.gate, classname=f"mrnc_eval.gates.{xml_text(s.log_id)}",
                                 time="0")
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
