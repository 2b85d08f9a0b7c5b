"""--sync interpolate against a closed form, --offset auto on a built pair with a known
offset, --decompose on a known lateral/vertical/yaw bias, and the CLI around them
(one warning line per messy file, --strict, JSON counts, the path plot)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.cli import main
from mrnc_eval.data import Trajectory
from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation.ape import ape
from mrnc_eval.evaluation.offset import estimate_offset
from mrnc_eval.geometry.interpolate import interpolate_at
from mrnc_eval.io.trajectory_files import write_tum

AXIS = np.array([0.36, 0.48, 0.8])  # unit rotation axis
RATE = 0.3  # rad/s about AXIS
VELOCITY = np.array([1.5, -0.4, 0.1])  # m/s


def constant_twist(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position linear in t, rotation at a constant rate about a fixed axis: linear
    interpolation and slerp between any two samples reproduce it exactly."""
    return 2.0 + np.outer(t, VELOCITY), Rotation.from_rotvec(np.outer(RATE * t, AXIS)).as_quat()


def test_interpolation_equals_closed_form_and_respects_max_gap() -> None:
    t = np.r_[np.arange(0.0, 5.0, 0.1), np.arange(5.5, 8.0, 0.1)]  # a 0.5 s gap after 4.9 s
    ref = Trajectory(t, *constant_twist(t), name="ref")
    rng = np.random.default_rng(0)
    query = np.sort(rng.uniform(-0.5, 8.5, 400))
    got, idx = interpolate_at(ref, query, max_gap=0.15)
    s = query[idx]
    assert np.all((s >= 0.0) & (s <= t[-1]))  # never extrapolated
    assert not np.any((s > 4.9 + 1e-9) & (s < 5.5 - 1e-9))  # not across the 0.5 s gap
    expected_outside = np.count_nonzero((query < 0) | (query > t[-1]) | ((query > 4.9) & (query < 5.5)))
    assert query.size - idx.size == expected_outside
    pos, quat = constant_twist(s)
    np.testing.assert_allclose(got.positions, pos, atol=1e-12)
    angle = (Rotation.from_quat(got.quat_xyzw).inv() * Rotation.from_quat(quat)).magnitude()
    assert angle.max() < 1e-12
    _, idx_wide = interpolate_at(ref, query, max_gap=0.6)
    assert idx_wide.size > idx.size  # the gap is bridged when allowed


def test_ape_with_interpolation_counts_unmatched_estimate_poses() -> None:
    t_ref = np.arange(0.0, 10.0, 0.1)
    ref = Trajectory(t_ref, *constant_twist(t_ref), name="ref")
    t_est = np.arange(-1.0, 12.0, 0.033)  # starts before and ends after the reference
    est = Trajectory(t_est, *constant_twist(t_est), name="est")
    r = ape(ref, est, sync="interpolate", align="none", relation="full")
    inside = np.count_nonzero((t_est >= 0.0) & (t_est <= t_ref[-1]))
    assert r.n == inside
    assert r.summary()["unmatched_est"] == t_est.size - inside
    assert r.stats["max"] < 1e-12  # the estimate is the closed form itself
    near = ape(ref, est, align="none", relation="trans", max_diff=0.01)  # nearest: snaps, so errs
    assert near.stats["max"] > 1e-3


def _wandering(t: np.ndarray, seed: int, noise: tuple[float, float]) -> tuple[np.ndarray, Rotation]:
    """A ground robot's path (turning and speed both varying), with pose noise (m, deg)."""
    rng = np.random.default_rng(seed)
    fine = np.arange(t.min() - 2.0, t.max() + 2.0, 0.001)
    yaw = 0.4 * np.sin(0.3 * fine) + 0.25 * np.sin(0.11 * fine + 1) + 0.05 * fine
    v = 1.0 + 0.3 * np.sin(0.2 * fine)
    x, y = np.cumsum(v * np.cos(yaw)) * 0.001, np.cumsum(v * np.sin(yaw)) * 0.001
    pos = np.c_[np.interp(t, fine, x), np.interp(t, fine, y), 0.1 * np.sin(0.5 * t)]
    rot = Rotation.from_euler("zyx", np.c_[np.interp(t, fine, yaw), 0.03 * np.sin(1.3 * t), 0.02 * np.cos(0.9 * t)])
    pos = pos + rng.normal(scale=noise[0], size=pos.shape)
    return pos, rot * Rotation.from_rotvec(rng.normal(scale=np.radians(noise[1]), size=(t.size, 3)))


def offset_pair(true_offset: float, seed: int = 1) -> tuple[Trajectory, Trajectory]:
    """Reference at 30 Hz (exact), estimate at 20 Hz (1 cm, 0.2 deg noise) in another frame,
    its clock `true_offset` s behind: est stamp + true_offset = reference time."""
    rng = np.random.default_rng(seed)
    t_ref = np.arange(0.0, 60.0, 1 / 30) + rng.uniform(0, 1 / 30)
    p, r = _wandering(t_ref, seed, (0.0, 0.0))
    ref = Trajectory(t_ref, p, r.as_quat(), name="ref")
    t_est = np.arange(0.0, 60.0, 1 / 20) + rng.uniform(0, 1 / 20)
    p, r = _wandering(t_est, seed + 100, (0.01, 0.2))
    frame = Rotation.from_euler("zyx", [0.7, 0.01, -0.02])
    est = Trajectory(t_est - true_offset, frame.apply(p) + [3.0, -1.0, 0.5], (frame * r).as_quat(), name="est")
    return ref, est


@pytest.mark.parametrize("true_offset", [0.1, -0.1])
def test_offset_auto_recovers_a_known_offset(true_offset: float) -> None:
    ref, est = offset_pair(true_offset)
    found = estimate_offset(ref, est)
    # measured: +0.0991 s and -0.1009 s (0.9 ms off; 1 cm / 0.2 deg pose noise on the estimate)
    assert abs(found.offset_s - true_offset) < 0.005
    assert found.correlation > 0.8
    at_zero = ape(ref, est, sync="interpolate")
    at_found = ape(ref, est, sync="interpolate", offset=found.offset_s)
    assert at_found.stats["rmse"] < 0.5 * at_zero.stats["rmse"]


def test_offset_auto_negative_control_without_shared_motion() -> None:
    """A circle at constant speed has no feature to lock on (and SE(3) alignment absorbs any
    shift along it): the speed signals do not correlate, so the test above could not pass."""
    t = np.arange(0.0, 30.0, 0.05)
    yaw = 0.2 * t
    circle = np.c_[5 * np.sin(yaw), 5 * (1 - np.cos(yaw)), np.zeros_like(t)]
    quat = Rotation.from_euler("z", yaw[:, None]).as_quat()
    rng = np.random.default_rng(2)
    ref = Trajectory(t, circle, quat)
    est = Trajectory(t - 0.1, circle + rng.normal(scale=0.01, size=circle.shape), quat)
    with pytest.raises(EvaluationError, match="do not correlate"):
        estimate_offset(ref, est)


def test_decompose_reads_back_a_known_bias() -> None:
    t = np.arange(0.0, 20.0, 0.05)
    yaw = 0.2 * t  # a left turn on a 5 m radius circle, heading along the path
    ref_xyz = np.c_[5 * np.sin(yaw), 5 * (1 - np.cos(yaw)), np.zeros_like(t)]
    left = np.c_[-np.sin(yaw), np.cos(yaw), np.zeros_like(t)]
    ahead = np.c_[np.cos(yaw), np.sin(yaw), np.zeros_like(t)]
    est_xyz = ref_xyz + 0.3 * left - 0.1 * ahead + [0.0, 0.0, 0.05]
    ref = Trajectory(t, ref_xyz, Rotation.from_euler("z", yaw[:, None]).as_quat())
    est = Trajectory(t, est_xyz, Rotation.from_euler("z", yaw[:, None] + np.radians(2.0)).as_quat())
    d = ape(ref, est, align="none").decompose().summary()
    assert d["cross_m"]["mean"] == pytest.approx(0.3, abs=2e-3)  # positive: to the left
    assert d["along_m"]["mean"] == pytest.approx(-0.1, abs=2e-3)  # behind
    assert d["vertical_m"]["mean"] == pytest.approx(0.05, abs=1e-12)
    assert d["yaw_deg"]["mean"] == pytest.approx(2.0, abs=1e-9)
    assert d["cross_m"]["std"] < 2e-3


def _messy_files(tmp_path: Path) -> tuple[Path, Path]:
    ref, est = offset_pair(0.0)
    rs = ref.stamps.copy()
    rs[100] = rs[99]
    es = est.stamps.copy()
    for k in (10, 300, 301, 650):
        es[k] = es[k - 1]
    write_tum(tmp_path / "gt.tum", Trajectory(rs, ref.positions, ref.quat_xyzw))
    write_tum(tmp_path / "est.tum", Trajectory(es, est.positions, est.quat_xyzw))
    return tmp_path / "gt.tum", tmp_path / "est.tum"


def test_cli_warns_once_per_file_and_strict_refuses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt, est = _messy_files(tmp_path)
    assert main(["ape", str(gt), str(est), str(est), "--json", "--max-diff", "0.02"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)["results"][0]
    assert out["repeated_stamps"] == {"reference": 1, "estimate": 4}
    lines = [ln.split(": ", 1)[1] for ln in captured.err.splitlines() if ln.startswith("WARNING")]
    assert lines == [f"{gt}: 1 repeated time stamp(s), paired as evo does (--strict refuses such files)",
                     f"{est}: 4 repeated time stamp(s), paired as evo does (--strict refuses such files)"]
    assert main(["ape", str(gt), str(est), "--strict"]) == 4
    assert "duplicate time stamp" in capsys.readouterr().err


def test_cli_offset_auto_interpolate_decompose_and_path_plot(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    ref, est = offset_pair(0.1)
    write_tum(tmp_path / "gt.tum", ref)
    write_tum(tmp_path / "est.tum", est)
    args = ["ape", str(tmp_path / "gt.tum"), str(tmp_path / "est.tum"), "--json"]
    assert main([*args, "--offset", "auto", "--sync", "interpolate", "--decompose",
                 "--plot", str(tmp_path / "path.svg")]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)["results"][0]
    assert abs(out["stats"]["offset_s"] - 0.1) < 0.005
    assert f"est: estimated clock offset {out['stats']['offset_s']:+.4f} s" in captured.err
    assert set(out["decomposition"]) == {"along_m", "cross_m", "vertical_m", "yaw_deg"}
    svg = (tmp_path / "path.svg").read_text()
    assert "reference" in svg
    assert "APE (m)" in svg
    assert main([*args, "--offset", "soon"]) == 2
    with pytest.raises(EvaluationError, match="max_gap"):
        ape(ref, est, sync="interpolate", max_gap=0.0)
