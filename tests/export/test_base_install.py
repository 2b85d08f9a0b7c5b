"""The base install (`pip install mrnc-eval`, no extras) runs info, ape, rpe, table, report, compare
and export; `slam` names the extra to install. Checked without a second environment: the verbs run
in a subprocess whose import system refuses the extras' modules (open3d, gtsam, numba, pykdtree,
weasyprint, kiss_icp), so a module-level import of any of them on these paths fails the test."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.evaluation.pairs import _walk_python

BLOCKED = ("open3d", "gtsam", "numba", "pykdtree", "weasyprint", "kiss_icp", "llvmlite")
REPO = Path(__file__).resolve().parents[2]

TEMPLATE = textwrap.dedent("""
    import importlib.abc, json, sys
    BLOCKED = {blocked!r}

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}} (blocked: base install)", name=name)
            return None

    sys.meta_path.insert(0, Block())
    from mrnc_eval.cli import main
    codes = {{}}
    for key, argv in json.loads(sys.argv[1]).items():
        codes[key] = main(argv)
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
    print(json.dumps({{"codes": codes, "leaked": leaked}}))
""")


def run_blocked(commands: dict[str, list[str]], cwd: Path, *,
                blocked: tuple[str, ...] = BLOCKED) -> tuple[dict[str, int], list[str], str]:
    env = {"PYTHONPATH": str(REPO), "HOME": str(cwd), "PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg"}
    script = TEMPLATE.format(blocked=blocked)
    proc = subprocess.run([sys.executable, "-c", script, json.dumps(commands)], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return out["codes"], out["leaked"], proc.stderr


def test_base_verbs_run_without_the_slam_stack_and_slam_names_its_extra(sim_runs, tmp_path: Path) -> None:
    log, slam_dir, control_dir = str(sim_runs.log), str(sim_runs.slam), str(sim_runs.control)
    seq = tmp_path / "seqs" / "yard"
    seq.mkdir(parents=True)
    (seq / "ground_truth.tum").write_text((sim_runs.slam / "trajectory.tum").read_text())
    (seq / "lio.tum").write_text((sim_runs.slam / "trajectory_online.tum").read_text())
    report_out = tmp_path / "report"
    commands = {
        "info": ["info", log, "--json"],
        "ape": ["ape", f"{log}:/ground_truth", f"{slam_dir}/trajectory.tum", "-a", "--max-diff", "0.02"],
        "rpe": ["rpe", f"{log}:/ground_truth", f"{slam_dir}/trajectory.tum", "-d", "0.5", "-u", "m",
                "--max-diff", "0.02"],
        "table": ["table", str(tmp_path / "seqs")],
        "report": ["report", slam_dir, control_dir, "--out", str(report_out)],
        "report_pdf": ["report", slam_dir, control_dir, "--out", str(tmp_path / "pdf_report"), "--pdf"],
        "compare": ["compare", slam_dir, slam_dir, "--format", "markdown"],
        "export": ["export", slam_dir, control_dir, "--mcap", str(tmp_path / "run.mcap"), "--with-log"],
        "slam": ["slam", log, "--out", str(tmp_path / "slam_out")],
        "simulate": ["simulate", str(tmp_path / "sim.mcap")],
    }
    codes, leaked, err = run_blocked(commands, tmp_path)
    assert leaked == []
    for verb in ("info", "ape", "rpe", "table", "compare", "export"):
        assert codes[verb] == 0, (verb, err[-2000:])
    assert codes["report"] in (0, 1), err[-2000:]  # 1: a gate failed on the tiny log; the report is written
    assert (report_out / "report.html").is_file()
    assert (tmp_path / "run.mcap").stat().st_size > 10_000
    # what needs an extra says which, exits 2 and writes nothing
    assert codes["slam"] == 2
    assert "pip install 'mrnc-eval[slam]'" in err
    assert codes["simulate"] == 2
    assert "mrnc-eval[sim]" in err
    assert codes["report_pdf"] == 2
    assert "mrnc-eval[pdf]" in err
    assert not (tmp_path / "pdf_report").exists()
    assert not (tmp_path / "slam_out").exists()
    assert not (tmp_path / "sim.mcap").exists()


def test_the_block_catches_a_module_level_import(tmp_path: Path) -> None:
    """Negative control: with the block, a verb that imports numba at module level (control) fails."""
    codes, _leaked, err = run_blocked({"control": ["control", "--mode", "simulate"]}, tmp_path)
    assert codes["control"] == 2
    assert "mrnc-eval[control]" in err


def test_nightly_without_numba_names_the_control_extra(tmp_path: Path) -> None:
    """The SLAM needs no numba (its kernels are C), the control chain does: nightly, which runs both,
    checks both extras before any work; without numba it names [control], not [slam]."""
    out = tmp_path / "night"
    codes, leaked, err = run_blocked({"nightly": ["nightly", str(REPO / "sample_logs"), "--out", str(out)]}, tmp_path,
                                     blocked=("numba", "llvmlite"))
    assert codes["nightly"] == 2
    assert "mrnc-eval[control]" in err
    assert "mrnc-eval[slam]" not in err
    assert leaked == []
    assert not out.exists()


def test_rpe_metre_pairs_without_numba_are_the_same_bits() -> None:
    """The Python walk of the base install against the compiled one (numba: the control and sim extras)."""
    from mrnc_eval.evaluation.pairs import _pairs_by_distance_incremental

    rng = np.random.default_rng(4)
    xyz = np.cumsum(rng.normal(scale=0.07, size=(20000, 3)), axis=0)
    steps = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    for delta in (0.1, 1.0, 7.3):
        fast = _pairs_by_distance_incremental(xyz, delta)
        slow = _walk_python(steps, delta)
        assert fast[0].size > 10
        np.testing.assert_array_equal(fast[0], slow[0])
        np.testing.assert_array_equal(fast[1], slow[1])


@pytest.mark.parametrize("path", ["pyproject.toml"])
def test_declared_dependencies_are_imported_somewhere(path: str) -> None:
    """A runtime dependency nobody imports (mcap-ros2-support was one) is not declared."""
    import re
    import tomllib

    deps = tomllib.loads((REPO / path).read_text())["project"]["dependencies"]
    names = {re.split(r"[<>=\[ ]", d)[0] for d in deps}
    import_name = {"pyyaml": "yaml", "rosbags": "rosbags", "typer": "typer"}
    source = "\n".join(p.read_text(encoding="utf-8") for p in (REPO / "mrnc_eval").rglob("*.py"))
    for name in names:
        module = import_name.get(name, name.replace("-", "_"))
        assert re.search(rf"^\s*(import|from) {module}\b", source, re.M), f"{name} is declared but never imported"
