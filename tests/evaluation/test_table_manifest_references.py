"""Issue 19 item 3: a `table` manifest takes every reference `ape` takes (one parser,
io/trajectory_inputs.py), relative to the manifest; the manifest format is documented in
`table --help` and in the README."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.cli import main
from mrnc_eval.commands.table import build_table_one
from mrnc_eval.data import Trajectory
from mrnc_eval.io.trajectory_files import write_tum
from mrnc_eval.io.trajectory_inputs import TrajectorySpec, parse_trajectory_spec
from mrnc_eval.io.writers import LogWriter

REPO = Path(__file__).resolve().parents[2]


def _drive(n: int = 400, noise_m: float = 0.0, seed: int = 0) -> Trajectory:
    """A 40 s drive at 10 Hz along a bent path; with `noise_m` of position noise."""
    t = 100.0 + np.arange(n) / 10.0
    xyz = np.stack([0.5 * t, 3.0 * np.sin(0.05 * t), 0.1 * np.cos(0.1 * t)], axis=1)
    xyz += np.random.default_rng(seed).normal(scale=noise_m, size=xyz.shape)
    return Trajectory(t, xyz, Rotation.from_euler("z", 0.15 * np.cos(0.05 * t)[:, None]).as_quat())


@pytest.fixture
def logged(tmp_path: Path) -> Path:
    """runs/drive.mcap with /ground_truth and /odom (Odometry), runs/est.tum, runs/m.yaml naming them
    relative to itself."""
    runs = tmp_path / "runs"
    runs.mkdir()
    with LogWriter(runs / "drive.mcap") as w:
        w.write_odometry("/ground_truth", _drive())
        w.write_odometry("/odom", _drive(noise_m=0.05, seed=1), frame_id="odom")
    write_tum(runs / "est.tum", _drive(noise_m=0.2, seed=2))
    (runs / "m.yaml").write_text(
        "sequences:\n"
        "  drive:\n"
        "    reference: drive.mcap:/ground_truth\n"
        "    methods:\n"
        "      odom: drive.mcap:/odom\n"
        "      tum: est.tum\n"
        "      typo: drive.mcap:/odmo\n", encoding="utf-8")
    return runs


def _ape_rmse(ref: str, est: str, capsys: pytest.CaptureFixture[str]) -> float:
    capsys.readouterr()
    assert main(["ape", ref, est, "--json", "--align", "se3"]) == 0  # as table aligns
    return float(json.loads(capsys.readouterr().out)["results"][0]["stats"]["rmse"])


def test_manifest_log_topics_are_read_as_ape_reads_them(logged: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str],
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # the manifest's paths are relative to it, not to where table runs
    table = build_table_one(logged / "m.yaml")
    col = {m: k for k, m in enumerate(table.column_labels)}
    odom, tum = table.cells[0][col["odom"]], table.cells[0][col["tum"]]
    assert odom == pytest.approx(_ape_rmse("runs/drive.mcap:/ground_truth", "runs/drive.mcap:/odom", capsys),
                                 rel=1e-12)
    assert tum == pytest.approx(_ape_rmse("runs/drive.mcap:/ground_truth", "runs/est.tum", capsys), rel=1e-9)
    assert 0.03 < odom < 0.12 < tum  # the noise put in, in order: not the same number twice
    assert table.cells[0][col["typo"]] == "Failed"
    assert any("/odmo" in note for note in table.notes)  # the reason names the topic


def test_one_reference_parser_for_ape_and_table(tmp_path: Path) -> None:
    base = tmp_path / "m"
    assert parse_trajectory_spec("a.mcap,b.mcap:/odom", base=base) == \
        TrajectorySpec(f"{base / 'a.mcap'},{base / 'b.mcap'}", "/odom")
    assert parse_trajectory_spec("log.bag:/tf:odom.base_link") == TrajectorySpec("log.bag", "/tf:odom.base_link")
    assert parse_trajectory_spec("bag_dir:/gt", base=base) == TrajectorySpec(str(base / "bag_dir"), "/gt")
    assert parse_trajectory_spec("/abs/est.tum", base=base) == TrajectorySpec("/abs/est.tum")


def test_table_help_and_readme_document_the_manifest(capsys: pytest.CaptureFixture[str],
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "240")
    assert main(["table", "--help"]) == 0
    shown = capsys.readouterr().out
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    for line in ("sequences:", "reference: forest.gt.tum", "methods:", "odometry: forest.mcap:/odom"):
        assert line in shown, f"table --help does not show the manifest line {line!r}"
        assert line in readme, f"the README does not show the manifest line {line!r}"
    assert "mrnc-eval table results/" in readme
