"""The rotation gate's z walk (issue 28, docs/simulation.md "Eighth session: the rotation gate's z
walk"): on bare ground a match's yaw jumps by degrees (a few far poles) while its tilt and z are
held by the ground. Rejecting the whole match for its yaw lets the IMU guess's tilt drift, gravity
leak into the vertical velocity and z walk; once the tilt error is beyond the gate every match is
rejected. slam.matching.max_tilt_correction_deg keeps the match's roll, pitch and z instead."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.replay import _Replay
from mrnc_eval.slam.scan_to_map import MatchResult, keep_tilt, tilt_correction_deg

DT = 0.2  # s per sweep
DRIFT_DEG = 0.1  # the guess's pitch drift per sweep (a gyro bias of 0.5 deg/s)
FREE = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])


def _match(pose: np.ndarray, guess: np.ndarray) -> MatchResult:
    return MatchResult(pose=pose, iterations=5, converged=True, degenerate=True, min_eigenvalue=10.0, n_edges=50,
                       n_surfs=500, optimised=True, n_degenerate=3, degenerate_directions=FREE.copy())


def _drive(max_tilt_deg: float, seed: int) -> tuple[float, float]:
    """200 sweeps level and still (the truth is the identity); 5-10 s an open stretch where every
    match's yaw is 2.5-6 deg off. Returns the largest tilt error (deg) and |z| at the end (m)."""
    cfg = SlamConfig()
    cfg = replace(cfg, matching=replace(cfg.matching, max_tilt_correction_deg=max_tilt_deg))
    gate = SimpleNamespace(cfg=cfg, wheel=None, events=[], gate_streak=0)
    rng = np.random.default_rng(seed)
    out, vz, worst = np.eye(4), 0.0, 0.0
    for k in range(200):
        guess = se3.make(out[:3, :3] @ rotation.from_rpy([0.0, np.radians(DRIFT_DEG), 0.0]),
                         out[:3, 3] + [0.0, 0.0, vz * DT])
        far = 25 <= k < 50 or rng.random() < 0.1
        yaw = rng.uniform(2.5, 6.0) * rng.choice([-1, 1]) if far else rng.normal(0.0, 0.5)
        tilt = rng.normal(0.0, 0.1, 2)
        heading = rotation.yaw_matrix(rotation.rpy(guess[:3, :3])[2])
        seen = se3.make(rotation.from_rpy(np.radians([*tilt, yaw])) @ heading,
                        [guess[0, 3], guess[1, 3], rng.normal(0.0, 0.02)])
        res = _Replay.gate_rotation(gate, _match(seen, guess), guess, k * DT)  # type: ignore[arg-type]
        out = res.pose
        err = float(np.degrees(rotation.angle(rotation.yaw_matrix(-rotation.rpy(out[:3, :3])[2]) @ out[:3, :3])))
        worst = max(worst, err)
        vz = 0.5 * vz if res.optimised else vz - 9.81 * np.sin(np.radians(err)) * DT  # gravity leaks in
    return worst, abs(float(out[2, 3]))


def test_a_match_turned_by_its_yaw_keeps_its_tilt_and_z() -> None:
    guess = se3.make(rotation.from_rpy(np.radians([1.0, -2.0, 30.0])), [1.0, 2.0, 3.0])
    seen = se3.make(rotation.from_rpy(np.radians([1.5, -1.2, 35.0])), [1.1, 2.2, 3.4])
    kept = keep_tilt(_match(seen, guess), guess)
    up = np.array([0.0, 0.0, 1.0])
    assert np.allclose(kept.pose[:3, :3].T @ up, seen[:3, :3].T @ up, atol=1e-9)  # the match's gravity direction
    assert abs(np.degrees(rotation.rpy(kept.pose[:3, :3])[2]) - 30.0) < 0.05  # the guess's yaw
    assert np.allclose(kept.pose[:3, 3], [1.0, 2.0, 3.4])
    assert kept.degenerate
    assert kept.degenerate_directions is not None
    assert len(kept.degenerate_directions) == 3
    assert abs(tilt_correction_deg(_match(seen, guess), guess) - 0.94) < 0.02


def test_the_gate_keeps_the_tilt_through_a_stretch_of_yaw_jumps() -> None:
    """Measured over 20 draws: with the tilt kept, the worst tilt error 0.42 deg and |z| at the end
    0.043 m at most; rejecting the whole match (the negative control, 0) locks out in every draw:
    tilt 17 deg and more, z hundreds of metres (this toy never recovers)."""
    kept = [_drive(2.0, seed) for seed in range(20)]
    rejected = [_drive(0.0, seed) for seed in range(20)]
    assert all(tilt < 0.8 and z < 0.1 for tilt, z in kept)
    assert all(tilt > 2.0 and z > 1.0 for tilt, z in rejected)


def test_a_false_match_that_tilts_is_still_rejected() -> None:
    """A match tilting the guess by 8 deg (a false match) keeps the guess whatever its yaw."""
    guess = np.eye(4)
    seen = se3.make(rotation.from_rpy(np.radians([8.0, 0.0, 3.0])), [0.0, 0.0, 0.3])
    res = _Replay.gate_rotation(SimpleNamespace(cfg=SlamConfig(), wheel=None, events=[], gate_streak=5),  # type: ignore[arg-type]
                                _match(seen, guess), guess, 0.0)
    assert not res.optimised
    assert np.array_equal(res.pose, guess)
