"""Association edge cases, formats, yaw alignment, drift and the paper's Table I."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.cli import main
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError, InputError
from mrnc_eval.evaluation.ape import ape
from mrnc_eval.evaluation.comparison import Cell, table_one
from mrnc_eval.evaluation.drift import kitti_drift, segment_lengths
from mrnc_eval.evaluation.sync import associate
from mrnc_eval.geometry import lie
from mrnc_eval.io.trajectory_files import read_trajectory, write_tum
from mrnc_eval.reports.tables import best_cells, render_table
from tests.evaluation.evo_reference import make_pair


def _traj(stamps, name="t") -> Trajectory:
    n = len(stamps)
    return Trajectory(np.asarray(stamps, float), np.c_[np.arange(n), np.sin(np.arange(n)), np.zeros(n)],
                      np.tile([0, 0, 0, 1.0], (n, 1)), name=name)


def test_no_overlap_is_a_clear_error() -> None:
    with pytest.raises(EvaluationError, match="no matching time stamps"):
        associate(_traj([0, 1, 2]), _traj([10, 11, 12]), max_diff=0.01)


def test_duplicate_and_unsorted_stamps_rejected_when_strict() -> None:
    with pytest.raises(EvaluationError, match="1 duplicate time stamp"):
        ape(_traj([0, 1, 1, 2]), _traj([0, 1, 2]), strict=True)
    with pytest.raises(EvaluationError, match=r"1 time stamp.*earlier"):
        ape(_traj([0, 1, 2, 3]), _traj([0, 2, 1, 3]), strict=True, align="none")
    counts = ape(_traj([0, 1, 1, 2]), _traj([0, 2, 1, 3]), align="none").summary()
    assert counts["repeated_stamps"] == {"reference": 1, "estimate": 0}
    assert counts["unsorted_stamps"] == {"reference": 0, "estimate": 1}


def test_single_pose_rejected() -> None:
    with pytest.raises(EvaluationError, match="1 pose"):
        ape(_traj([0, 1, 2]), _traj([1]))


def test_unsorted_input_is_sorted_not_misread() -> None:
    ref = _traj(np.arange(50) * 0.1)
    order = np.random.default_rng(0).permutation(50)
    shuffled = Trajectory(ref.stamps[order], ref.positions[order], ref.quat_xyzw[order], name="shuffled")
    r = ape(ref, shuffled, align="none")
    assert r.n == 50
    assert r.stats["max"] == 0.0


def test_ties_go_to_the_earlier_stamp() -> None:
    m = associate(_traj([0.0, 0.02, 0.04, 0.06]), _traj([0.01, 0.03]), max_diff=0.01)
    np.testing.assert_array_equal(m.ref_idx, [0, 1])


def test_yaw_alignment_recovers_a_planar_offset() -> None:
    ref, _ = make_pair(seed=2)
    rot = Rotation.from_euler("z", 1.1)
    est = Trajectory(ref.stamps, rot.apply(ref.positions) + [5, -3, 0.2],
                     (rot * Rotation.from_quat(ref.quat_xyzw)).as_quat(), name="yawed")
    r = ape(ref, est, align="yaw", relation="trans")
    assert r.stats["max"] < 1e-9
    assert r.alignment.rotation[2, 2] == pytest.approx(1.0)
    assert ape(ref, est, align="none").stats["rmse"] > 1.0


def test_yaw_alignment_is_least_squares_optimal_under_noise() -> None:
    """With noise and a tilt the closed form must still be the best yaw + translation: any
    small change of the yaw (with the translation re-fitted) raises the sum of squares."""
    ref, est = make_pair(seed=4)  # est: 3-D rotated (incl. roll/pitch), scaled, noisy
    r = ape(ref, est, align="yaw")
    yaw = np.arctan2(r.alignment.rotation[1, 0], r.alignment.rotation[0, 0])
    p, q = r.pair.est.positions, r.pair.ref.positions

    def sse(a: float) -> float:
        rz = Rotation.from_euler("z", a).as_matrix()
        moved = p @ rz.T
        return float(np.sum((q - moved - (q - moved).mean(axis=0)) ** 2))

    assert r.stats["sse"] == pytest.approx(sse(yaw), rel=1e-9)
    assert sse(yaw) < min(sse(yaw + 1e-4), sse(yaw - 1e-4))


def test_tum_kitti_euroc_round_trip(tmp_path: Path) -> None:
    ref, _ = make_pair(n=50)
    write_tum(tmp_path / "a.tum", ref)
    back = read_trajectory(tmp_path / "a.tum")
    np.testing.assert_allclose(back.positions, ref.positions, atol=1e-9)
    t = lie.poses(ref)
    np.savetxt(tmp_path / "k.txt", t[:, :3, :].reshape(-1, 12))
    k = read_trajectory(tmp_path / "k.txt")
    np.testing.assert_allclose(lie.poses(k), t, atol=1e-9)
    q = ref.quat_xyzw
    np.savetxt(tmp_path / "data.csv",
               np.c_[(ref.stamps * 1e9).round(), ref.positions, q[:, 3], q[:, :3], np.zeros((50, 9))],
               delimiter=",", header="timestamp,p_x,...", comments="#")
    e = read_trajectory(tmp_path / "data.csv")
    np.testing.assert_allclose(e.quat_xyzw, q, atol=1e-12)
    np.testing.assert_allclose(e.stamps, ref.stamps, atol=1e-9)


def test_ragged_tum_names_file_and_line(tmp_path: Path) -> None:
    p = tmp_path / "bad.tum"
    p.write_text("0 1 2 3 0 0 0 1\n1 1 2 3 0 0 1\n")
    with pytest.raises(InputError, match=r"bad\.tum.*line 2 has 7 fields"):
        read_trajectory(p)


def test_ape_cli_json_keys(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    ref, est = make_pair(n=200)
    write_tum(tmp_path / "gt.tum", ref)
    write_tum(tmp_path / "est.tum", est)
    assert main(["ape", str(tmp_path / "gt.tum"), str(tmp_path / "est.tum"), "--json", "--max-diff", "0.01"]) == 0
    out = json.loads(capsys.readouterr().out)["results"]
    assert out[0]["name"] == "est"
    assert set(out[0]["stats"]) >= {"rmse", "mean", "median", "std", "min", "max", "sse", "n"}
    assert main(["ape", str(tmp_path / "gt.tum"), str(tmp_path / "missing.tum")]) == 4


def test_drift_of_a_perfect_estimate_is_zero_and_scaled_lengths_are_stated() -> None:
    ref, _ = make_pair(n=2000)
    t = lie.poses(ref)
    d = kitti_drift(t, t)
    assert d.mean_trans_pct < 1e-9
    assert len(d.lengths_m) == 8
    assert d.lengths_m[-1] < 100
    assert segment_lengths(2000.0)[0] == 100.0
    # on a straight path a 1 % scale error is exactly 1 % translational drift
    t[:, :3, 3] = np.c_[np.arange(2000) * 0.05, np.zeros(2000), np.zeros(2000)]
    s = t.copy()
    s[:, :3, 3] *= 1.01
    assert kitti_drift(t, s).mean_trans_pct == pytest.approx(1.0, rel=1e-3)  # segments end at the first pose past L


# ------------------------------------------------------------------ the paper's Table I

PAPER_METHODS = ["LIO-SAM", "FAST-LIO2", "ORB-SLAM3", "ORB-SLAM3 inertial", "VINS-Fusion", "VINS-Fusion inertial"]
PAPER_ROWS = {  # shared/paper, table "ape_results" (m); None = "Failed"
    "1": [0.217127, 0.409905, 0.164774, 0.485586, 0.474715, 0.440113],
    "2": [0.86914, 1.754343, None, 1.715077, 2.216691, 1.925925],
    "3": [0.81162, 1.555683, 0.542835, 1.252041, 1.387264, 1.23698],
    "4": [0.417588, 0.70375, 0.280474, 0.516507, 0.529805, 0.454944],
    "5": [0.681154, 1.664873, 0.440216, 1.520726, 1.743379, 1.691131],
    "6": [0.869949, 1.886515, 0.735056, 1.968528, 3.277011, 2.850892],
    "7": [0.088294, 0.189954, 0.103472, 0.198334, 1.130662, 0.889479],
    "8": [0.941384, 0.993397, 0.879032, 1.466838, 2.90835, 2.532334],
    "9": [0.768462, 0.82185, 0.851645, 1.379856, 1.742125, 1.593643],
    "10": [0.903748, 1.524194, 0.860641, None, 3.012128, 2.583019],
}
PAPER_BOLD = {"1": "ORB-SLAM3", "2": "LIO-SAM", "3": "ORB-SLAM3", "4": "ORB-SLAM3", "5": "ORB-SLAM3",
              "6": "ORB-SLAM3", "7": "LIO-SAM", "8": "ORB-SLAM3", "9": "LIO-SAM", "10": "ORB-SLAM3"}
PAPER_MEAN = ["0.6568466", "1.1504464", "0.53979389", "1.16705478", "1.842213", "1.619846"]


def test_reproduces_paper_table_one() -> None:
    cells = {(s, m): Cell(v) if v is not None else Cell(None, "tracking lost")
             for s, vals in PAPER_ROWS.items() for m, v in zip(PAPER_METHODS, vals, strict=False)}
    table = table_one(cells, list(PAPER_ROWS), PAPER_METHODS, precision=6)
    bold = best_cells(table)
    for r, seq in enumerate(PAPER_ROWS):
        assert {PAPER_METHODS[c] for rr, c in bold if rr == r} == {PAPER_BOLD[seq]}, seq
    assert table.cells[1][2] == "Failed"
    assert table.cells[9][3] == "Failed"
    for k, printed in enumerate(PAPER_MEAN):  # the paper's mean row, digit for digit at its printed precision
        decimals = len(printed.split(".")[1])
        assert f"{table.cells[-1][k]:.{decimals}f}" == printed, PAPER_METHODS[k]
    assert "ORB-SLAM3 9/10" in table.notes[0]
    assert "LIO-SAM 10/10" in table.notes[0]
    # Mean row: the lowest mean (ORB-SLAM3, over 9 sequences) is marked. The paper also bolds
    # LIO-SAM's mean, the lowest among methods that completed all ten; we name it in a note.
    assert {PAPER_METHODS[c] for r, c in bold if r == len(PAPER_ROWS)} == {"ORB-SLAM3"}
    assert "without a Failed sequence: LIO-SAM (0.656847)" in table.notes[1]
    md, tex, html, csv = (render_table(table, f) for f in ("markdown", "latex", "html", "csv"))
    assert "**0.164774**" in md
    assert "\\textbf{0.086294}" not in tex
    assert "\\toprule" in tex
    assert "<strong>0.088294</strong>" in html
    assert "Failed" in csv


def test_table_from_directory_marks_short_tracking_as_failed(tmp_path: Path) -> None:
    ref, est = make_pair(n=1000)
    seq = tmp_path / "seq1"
    seq.mkdir()
    write_tum(seq / "ground_truth.tum", ref)
    write_tum(seq / "good.tum", est)
    half = Trajectory(est.stamps[:400], est.positions[:400], est.quat_xyzw[:400], name="half")
    write_tum(seq / "half.tum", half)
    from mrnc_eval.commands.table import build_table_one

    table = build_table_one(tmp_path)  # evaluation.max_diff_s 0.01
    assert table.column_labels == ["good", "half"]
    assert isinstance(table.cells[0][0], float)
    assert table.cells[0][1] == "Failed"
    assert any("covers" in n for n in table.notes)
