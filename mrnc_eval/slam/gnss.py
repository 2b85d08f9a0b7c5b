"""GNSS factors for graph #1. LIO-SAM receives GNSS already in its odom frame (navsat_transform
with a magnetometer heading); a 6-axis replay has no heading, so the ENU -> map yaw and offset
are estimated from the first `align_min_travel_m` of keyframes (2-D Umeyama, rotation about z
plus translation), then fixes enter as GPS factors under LIO-SAM's gates."""

from __future__ import annotations

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.slam.config import GpsConfig


def fit_yaw_translation(src_xy: np.ndarray, dst_xy: np.ndarray) -> tuple[float, np.ndarray]:
    """yaw, t minimising sum |R(yaw) src + t - dst|^2 (closed form)."""
    ms, md = src_xy.mean(axis=0), dst_xy.mean(axis=0)
    a, b = src_xy - ms, dst_xy - md
    cross = np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    dot = np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
    yaw = float(np.arctan2(cross, dot))
    c, s = np.cos(yaw), np.sin(yaw)
    return yaw, md - np.array([[c, -s], [s, c]]) @ ms


class GnssAligner:
    def __init__(self, gnss: GnssSeries, cfg: GpsConfig, antenna_in_sensor: np.ndarray | None) -> None:
        self.gnss, self.cfg = gnss, cfg
        self.lever = np.zeros(3) if antenna_in_sensor is None else np.asarray(antenna_in_sensor, float)
        self.enu_to_map: tuple[float, np.ndarray] | None = None
        self.pairs_map: list[np.ndarray] = []
        self.pairs_enu: list[np.ndarray] = []

    def _fix_near(self, t: float) -> int | None:
        i = int(np.argmin(np.abs(self.gnss.stamps - t)))
        return i if abs(self.gnss.stamps[i] - t) <= self.cfg.max_time_diff_s else None

    def _to_map(self, enu: np.ndarray) -> np.ndarray:
        yaw, t = self.enu_to_map
        c, s = np.cos(yaw), np.sin(yaw)
        xy = np.array([[c, -s], [s, c]]) @ enu[:2] + t
        return np.r_[xy, enu[2]]

    def maybe_add(self, graph, stamp: float, events: list) -> bool:
        """Called at each new keyframe; returns True when a GNSS factor was added."""
        from mrnc_eval.slam.replay import SlamEvent

        g = self.cfg
        i = self._fix_near(stamp)
        pose = graph.poses[-1]
        antenna = pose[:3, :3] @ self.lever + pose[:3, 3]
        if self.enu_to_map is None:
            if i is not None and np.all(np.diag(self.gnss.covariance[i])[:2] <= g.gps_cov_threshold_m2):
                self.pairs_map.append(antenna[:2])
                self.pairs_enu.append(self.gnss.enu[i, :2])
            travel = np.linalg.norm(self.pairs_map[-1] - self.pairs_map[0]) if self.pairs_map else 0.0
            if len(self.pairs_map) >= 3 and travel >= g.align_min_travel_m:
                self.enu_to_map = fit_yaw_translation(np.array(self.pairs_enu), np.array(self.pairs_map))
                events.append(SlamEvent(stamp, "gps", f"ENU -> map alignment from {len(self.pairs_map)} fixes: "
                                        f"yaw {np.degrees(self.enu_to_map[0]):.1f} deg"))
            return False
        if len(graph.poses) < 2 or np.linalg.norm(pose[:3, 3] - graph.poses[0][:3, 3]) < g.min_travel_m:
            return False
        if graph.xy_variance() < g.pose_cov_threshold_m2:
            return False  # LIO-SAM adds GNSS only once the pose has become uncertain
        if i is None:
            return False
        var = np.diag(self.gnss.covariance[i]).copy()
        if var[0] > g.gps_cov_threshold_m2 or var[1] > g.gps_cov_threshold_m2:
            return False
        p = self._to_map(self.gnss.enu[i])
        if not g.use_elevation:
            p[2], var[2] = antenna[2], 0.01
        if abs(p[0]) < 1e-6 and abs(p[1]) < 1e-6:
            return False  # LIO-SAM skips (0, 0): an uninitialised fix
        if graph.last_gps_xy is not None and np.linalg.norm(p[:2] - graph.last_gps_xy) < g.min_spacing_m:
            return False
        graph.add_gps(len(graph.poses) - 1, p, var, self.lever)
        events.append(SlamEvent(stamp, "gps", f"GNSS factor at keyframe {len(graph.poses) - 1}"))
        return True
