"""GNSS factors for graph #1. LIO-SAM receives GNSS already in its odom frame (navsat_transform
with a magnetometer heading); a 6-axis replay has no heading, so the ENU -> map yaw and offset
are estimated from the first `align_min_travel_m` of keyframes (2-D Umeyama, rotation about z
plus translation: geometry.point_fit.yaw_align), then fixes enter as GPS factors under LIO-SAM's gates."""

from __future__ import annotations

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.geometry.point_fit import yaw_align
from mrnc_eval.slam.config import GpsConfig
from mrnc_eval.slam.gnss_gate import gate
from mrnc_eval.slam.graph import KeyframeGraph
from mrnc_eval.slam.output import SlamEvent


def fit_yaw_translation(src_xy: np.ndarray, dst_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2x2 rotation R(yaw) and t minimising sum |R src + t - dst|^2 (the evaluation's 4-DoF fit on z = 0)."""
    r, t = yaw_align(_on_ground(src_xy), _on_ground(dst_xy))
    return r[:2, :2], t[:2]


def _on_ground(xy: np.ndarray) -> np.ndarray:
    return np.asarray(np.c_[xy, np.zeros(len(xy))], np.float64)


class GnssAligner:
    """Estimates the ENU -> map alignment, then adds GNSS factors at keyframes under LIO-SAM's gates."""

    def __init__(self, gnss: GnssSeries, cfg: GpsConfig, antenna_in_sensor: np.ndarray | None) -> None:
        self.gnss, self.cfg = gnss, cfg
        self.lever = np.zeros(3) if antenna_in_sensor is None else np.asarray(antenna_in_sensor, float)
        self.enu_to_map: tuple[np.ndarray, np.ndarray] | None = None  # 2x2 rotation, translation (m)
        self.pairs_map: list[np.ndarray] = []
        self.pairs_enu: list[np.ndarray] = []
        self.velocity_error: np.ndarray | None = None  # (2,) m/s map frame, of the latest residual-gate factor
        self.wheels = False  # wheel factors bound the chain's drift (residual gate's chain sigma)
        self.last_factor_kf = 0  # keyframe of the latest residual-gate factor

    def _fix_near(self, t: float) -> int | None:
        i = int(np.argmin(np.abs(self.gnss.stamps - t)))
        return i if abs(self.gnss.stamps[i] - t) <= self.cfg.max_time_diff_s else None

    def _to_map(self, enu: np.ndarray, enu_to_map: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        rot, t = enu_to_map
        return np.asarray(np.r_[rot @ enu[:2] + t, enu[2]], np.float64)

    def maybe_add(self, graph: KeyframeGraph, stamp: float, events: list[SlamEvent]) -> bool:
        """Called at each new keyframe; returns True when a GNSS factor was added."""
        if self.cfg.gate == "residual":
            return self.maybe_add_residual(graph, stamp, events)
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
                yaw = np.arctan2(self.enu_to_map[0][1, 0], self.enu_to_map[0][0, 0])
                events.append(SlamEvent(t=stamp, kind="gps",
                                        message=f"ENU -> map alignment from {len(self.pairs_map)} fixes: "
                                        f"yaw {np.degrees(yaw):.1f} deg"))
            return False
        if len(graph.poses) < 2 or np.linalg.norm(pose[:3, 3] - graph.poses[0][:3, 3]) < g.min_travel_m:
            return False
        if i is None:
            return False
        var = np.diag(self.gnss.covariance[i]).copy()
        if var[0] > g.gps_cov_threshold_m2 or var[1] > g.gps_cov_threshold_m2:
            return False
        rtk = 0 < max(var[0], var[1]) <= g.rtk_max_variance_m2
        if graph.xy_variance() < (max(var[0], var[1]) if rtk else g.pose_cov_threshold_m2):
            return False  # LIO-SAM adds GNSS only once the pose has become uncertain (RTK: less certain than it)
        p = self._to_map(self.gnss.enu[i], self.enu_to_map)
        if not g.use_elevation:
            p[2], var[2] = antenna[2], 0.01
        if abs(p[0]) < 1e-6 and abs(p[1]) < 1e-6:
            return False  # LIO-SAM skips (0, 0): an uninitialised fix
        spacing = g.rtk_min_spacing_m if rtk else g.min_spacing_m
        if graph.last_gps_xy is not None and np.linalg.norm(p[:2] - graph.last_gps_xy) < spacing:
            return False
        graph.add_gps(len(graph.poses) - 1, p, var, self.lever, floor_m2=0.0 if rtk else 1.0)
        events.append(SlamEvent(t=stamp, kind="gps", message=f"GNSS factor at keyframe {len(graph.poses) - 1}"))
        return True

    def maybe_add_residual(self, graph: KeyframeGraph, stamp: float, events: list[SlamEvent]) -> bool:
        """slam/gnss_gate.py: a factor when the recent fixes' median residual says the chain drifted."""
        g = self.cfg
        var = np.diagonal(self.gnss.covariance, axis1=1, axis2=2)
        usable = np.all(var[:, :2] <= g.gps_cov_threshold_m2, axis=1) & np.all(np.isfinite(self.gnss.enu), axis=1)
        chain_sigma = None
        if self.wheels:  # the wheels bound the drift: a fraction of the distance since the last factor
            since = np.asarray([p[:3, 3] for p in graph.poses[self.last_factor_kf:]])
            travel = float(np.linalg.norm(np.diff(since, axis=0), axis=1).sum()) if len(since) > 1 else 0.0
            chain_sigma = g.residual_chain_floor_m + g.residual_chain_drift_fraction * travel
        decision, align = gate(self.gnss, usable, np.asarray(graph.stamps), np.asarray(graph.poses), self.lever, g,
                               chain_sigma)
        if align is not None and self.enu_to_map is None:
            yaw = np.arctan2(align[0][1, 0], align[0][0, 0])
            events.append(SlamEvent(t=stamp, kind="gps", message=f"ENU -> map alignment (re-fitted at every keyframe) "
                                    f"from the fixes so far: yaw {np.degrees(yaw):.1f} deg"))
        if align is not None:
            self.enu_to_map = align
        if decision is None or decision.position is None:
            return False
        if graph.last_gps_xy is not None and np.linalg.norm(decision.position[:2] - graph.last_gps_xy) \
                < g.residual_min_spacing_m:
            return False
        assert decision.variance is not None
        self.velocity_error = decision.velocity_error
        self.last_factor_kf = len(graph.poses) - 1
        graph.add_gps(len(graph.poses) - 1, decision.position, decision.variance, self.lever, floor_m2=0.0,
                      huber_k=g.residual_huber_k)
        events.append(SlamEvent(t=stamp, kind="gps", message=f"GNSS factor at keyframe {len(graph.poses) - 1}: the "
                                f"chain is {np.linalg.norm(decision.residual_m):.2f} m +- {decision.sigma_m:.2f} m off "
                                f"the fixes ({decision.inliers} inliers, {decision.outliers} outliers)",
                                data={"residual_m": float(np.linalg.norm(decision.residual_m)),
                                      "sigma_m": decision.sigma_m, "inliers": decision.inliers,
                                      "outliers": decision.outliers}))
        return True
