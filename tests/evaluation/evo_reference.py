"""Generated trajectories and evo (test-only dependency, GPL: used, never copied) as reference."""

from __future__ import annotations

import copy

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.data import Trajectory
from tests.needs import need_module


def require_evo() -> None:
    """evo is the independent reference of the APE/RPE claims: with CI=true a missing evo
    fails the tests (it must not silently skip them); elsewhere they skip with the reason."""
    need_module("evo", "evo is not installed (pip install 'mrnc-eval[test]'): the evo cross-checks cannot run")


def make_pair(n: int = 600, seed: int = 0, dt_offset: float = 0.003, rate: float = 100.0):
    """A smooth 3-D path (ground truth) and a noisy, offset, rotated, scaled estimate."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    pos = np.stack([10 * np.sin(0.1 * t), 6 * np.sin(0.2 * t), 0.5 * np.sin(0.05 * t)], axis=1)
    yaw = 0.3 * t + 0.2 * np.sin(t)
    rot = Rotation.from_euler("zyx", np.stack([yaw, 0.05 * np.sin(0.7 * t), 0.04 * np.cos(0.3 * t)], axis=1))
    ref = Trajectory(t, pos, rot.as_quat(), name="gt")
    offset = Rotation.from_euler("zyx", [0.4, 0.02, -0.03])
    pos_e = 1.05 * offset.apply(pos + rng.normal(scale=0.05, size=pos.shape)) + [3.0, -2.0, 0.5]
    rot_e = offset * rot * Rotation.from_rotvec(rng.normal(scale=0.01, size=(n, 3)))
    est = Trajectory(t + dt_offset + rng.uniform(-0.002, 0.002, n), pos_e, rot_e.as_quat(), name="est")
    return ref, est


def to_evo(traj: Trajectory):
    from evo.core.trajectory import PoseTrajectory3D

    q = traj.quat_xyzw
    return PoseTrajectory3D(positions_xyz=traj.positions.copy(), orientations_quat_wxyz=q[:, [3, 0, 1, 2]].copy(),
                            timestamps=traj.stamps.copy())


EVO_RELATION = {"trans": "translation_part", "rot": "rotation_part", "full": "full_transformation",
                "angle_deg": "rotation_angle_deg", "angle_rad": "rotation_angle_rad", "point": "point_distance"}


def evo_prepare(ref: Trajectory, est: Trajectory, *, align: str, max_diff: float, offset: float,
                n_to_align: int | None, plane: str | None):
    from evo.core import sync

    r, e = sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=max_diff, offset_2=offset)
    r, e = copy.deepcopy(r), copy.deepcopy(e)
    n = -1 if n_to_align is None else n_to_align
    if align == "se3":
        e.align(r, correct_scale=False, n=n)
    elif align == "sim3":
        e.align(r, correct_scale=True, n=n)
    elif align == "scale":
        e.align(r, correct_only_scale=True, n=n)
    elif align == "origin":
        e.align_origin(r)
    if plane:
        from evo.core.trajectory import Plane

        pl = Plane(plane)
        r.project(pl)
        e.project(pl)
    return r, e


def evo_ape(ref, est, *, relation, align="se3", max_diff=0.01, offset=0.0, n_to_align=None, plane=None):
    from evo.core import metrics

    r, e = evo_prepare(ref, est, align=align, max_diff=max_diff, offset=offset, n_to_align=n_to_align, plane=plane)
    m = metrics.APE(getattr(metrics.PoseRelation, EVO_RELATION[relation]))
    m.process_data((r, e))
    return m.get_all_statistics(), m.error


def evo_rpe(ref, est, *, relation, delta, unit, all_pairs=False, align="none", max_diff=0.01, offset=0.0,
            pairs_from_reference=False):
    from evo.core import metrics

    r, e = evo_prepare(ref, est, align=align, max_diff=max_diff, offset=offset, n_to_align=None, plane=None)
    u = metrics.Unit.frames if unit == "frames" else metrics.Unit.meters
    m = metrics.RPE(getattr(metrics.PoseRelation, EVO_RELATION[relation]), delta=delta, delta_unit=u,
                    all_pairs=all_pairs, pairs_from_reference=pairs_from_reference)
    m.process_data((r, e))
    return m.get_all_statistics(), m.error
