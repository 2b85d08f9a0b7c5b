"""geometry.rotation (the SLAM's own rotation helpers, no scipy at run time) against scipy's Rotation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from mrnc_eval.geometry import rotation

TOL = 1e-12


def _rotations(n: int = 500, seed: int = 0) -> Rotation:
    """Random rotations plus the awkward ones: identity, tiny angles, angles near pi, gimbal lock."""
    rng = np.random.default_rng(seed)
    special = [np.zeros(3), [1e-9, 0, 0], [3e-5, -2e-5, 1e-5], [0, 0, np.pi - 1e-9], [np.pi, 0, 0],
               [0, np.pi / 2, 0], [0.3, np.pi / 2 - 1e-3, -0.2]]
    vecs = np.r_[np.asarray(special, float), rng.normal(size=(n, 3)) * rng.uniform(0, 1, (n, 1))]
    return Rotation.from_rotvec(vecs)


def _same_rotation(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, rtol=0, atol=TOL)


def test_quaternion_and_matrix_round_trips_match_scipy() -> None:
    r = _rotations()
    q = r.as_quat() * np.linspace(0.5, 2.0, len(r))[:, None]  # any norm
    _same_rotation(rotation.quat_to_matrix(q), Rotation.from_quat(q).as_matrix())
    m = r.as_matrix()
    np.testing.assert_allclose(rotation.matrix_to_quat(m), Rotation.from_matrix(m).as_quat(), rtol=0, atol=TOL)
    np.testing.assert_allclose(rotation.matrix_to_quat(m[3]), Rotation.from_matrix(m[3]).as_quat(), rtol=0, atol=TOL)
    rough = m + 1e-7 * np.random.default_rng(1).normal(size=m.shape)  # printed to limited precision
    np.testing.assert_allclose(rotation.matrix_to_quat(rough), Rotation.from_matrix(rough).as_quat(), rtol=0,
                               atol=1e-10)


def test_exp_and_log_match_scipy_at_every_angle() -> None:
    r = _rotations()
    v = r.as_rotvec()
    _same_rotation(rotation.exp(v), r.as_matrix())
    _same_rotation(rotation.exp(v[5]), r[5].as_matrix())
    got = rotation.log(r.as_matrix())
    near_pi = np.linalg.norm(v, axis=1) > np.pi - 1e-6  # +v and -v are the same rotation there
    np.testing.assert_allclose(got[~near_pi], v[~near_pi], rtol=0, atol=TOL)
    _same_rotation(rotation.exp(got[near_pi]), r[near_pi].as_matrix())
    np.testing.assert_allclose(rotation.angle(r.as_matrix()), r.magnitude(), rtol=0, atol=TOL)
    for i in range(40):  # one rotation at a time: the Python-float paths
        _same_rotation(rotation.exp(v[i]), r[i].as_matrix())
        _same_rotation(rotation.exp(rotation.log(r[i].as_matrix())), r[i].as_matrix())
        if not near_pi[i]:
            np.testing.assert_allclose(rotation.log(r[i].as_matrix()), v[i], rtol=0, atol=TOL)
        np.testing.assert_allclose(rotation.matrix_to_quat(r[i].as_matrix()), r[i].as_quat(), rtol=0, atol=TOL)


@pytest.mark.filterwarnings("ignore:Gimbal lock")
def test_roll_pitch_yaw_matches_scipy_xyz_and_zyx() -> None:
    r = _rotations()
    m = r.as_matrix()
    locked = np.abs(np.abs(r.as_euler("xyz")[:, 1]) - np.pi / 2) < 1e-6  # scipy warns and picks another split
    got = rotation.rpy(m)
    np.testing.assert_allclose(got[~locked], r.as_euler("xyz")[~locked], rtol=0, atol=TOL)
    np.testing.assert_allclose(got[~locked][:, ::-1], r.as_euler("ZYX")[~locked], rtol=0, atol=TOL)
    _same_rotation(rotation.from_rpy(got), m)  # gimbal lock too: the split differs, the rotation does not
    _same_rotation(rotation.from_rpy(got[7]), m[7])
    yaw = np.linspace(-4, 4, 9)
    _same_rotation(rotation.yaw_matrix(yaw), Rotation.from_euler("z", yaw[:, None]).as_matrix())


def test_slerp_matches_scipy() -> None:
    r = _rotations(50, seed=2)
    for i in range(len(r) - 1):
        for a in (0.0, 0.3, 0.5, 1.0):
            want = Slerp([0.0, 1.0], r[i:i + 2])([a])[0].as_matrix()
            _same_rotation(rotation.slerp(r[i].as_matrix(), r[i + 1].as_matrix(), a), want)
