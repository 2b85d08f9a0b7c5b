"""The SLAM replay, sweep by sweep, in LIO-SAM's order:
skip (mappingProcessInterval) -> range image -> deskew -> features -> guess from graph #2 ->
scan-to-map -> graph #2 correction -> keyframe: graph #1, GNSS, loop closure, local map."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mrnc_eval.data import GnssSeries, ImuSeries, Sweep
from mrnc_eval.errors import ProcessingError
from mrnc_eval.geometry import rotation, se3
from mrnc_eval.slam import gnss_ins
from mrnc_eval.slam.config import SlamConfig
from mrnc_eval.slam.deskew import deskew
from mrnc_eval.slam.features import Features, extract_features, voxel_downsample
from mrnc_eval.slam.gnss import GnssAligner
from mrnc_eval.slam.gnss_track import GnssTrack, move_along_free, track_filter
from mrnc_eval.slam.gnss_track import build as build_gnss_track
from mrnc_eval.slam.graph import KeyframeGraph, icp_min_eigenvalue, loop_candidate, register_loop
from mrnc_eval.slam.imu import (
    ImuOdometry,
    ImuTrack,
    bumpy_start_attitude,
    clean_imu,
    driving_attitude,
    imu_track,
    initial_attitude,
    lidar_to_imu,
)
from mrnc_eval.slam.imu_noise import ImuNoiseEstimate, StandingStartBias, estimate_imu_noise, standing_start_bias
from mrnc_eval.slam.map_quality import MapQuality, map_quality
from mrnc_eval.slam.mapping_interval import MappingInterval
from mrnc_eval.slam.nearest import KdTree
from mrnc_eval.slam.offset_rematch import RunForOffset, SweepStore, rematch_time_offset
from mrnc_eval.slam.output import STAGES, SlamEvent, SlamOutput
from mrnc_eval.slam.range_image import RangeImage
from mrnc_eval.slam.scan_to_map import LocalMap, MatchResult, keep_tilt, match, tilt_correction_deg
from mrnc_eval.slam.sweep_prep import PreparedSweep, prepare_sweep
from mrnc_eval.slam.time_offset import SEARCH_S, OffsetEstimate, imu_time_offset
from mrnc_eval.slam.warmup import warm_up
from mrnc_eval.slam.wheel_calibration import WheelCalibrator
from mrnc_eval.slam.wheel_gnss_scale import GnssScale, gnss_scale
from mrnc_eval.slam.wheel_health import wheel_health
from mrnc_eval.slam.wheel_odometry import WheelTrack, base_velocity, blend_planar, relative_motion, wheel_factor

__all__ = ["STAGES", "SlamEvent", "SlamOutput", "run_slam"]


def start_anchored(cfg: SlamConfig, with_wheels: bool) -> bool:
    """Whether the first keyframe is anchored (graph.anchored_prior_variances) instead of LIO-SAM's
    free start. with_wheels: only when wheel factors are in the graph. Not without wheels whatever
    the GNSS gate: on bare ground x, y and yaw are IMU dead reckoning there, and an anchored start
    holds that drift against the fixes (open line, no wheels, float GNSS, tuning seeds 0-2, online
    APE: 50.1 / 32.9 / 33.9 m anchored, 7.3 / 15.3 / 7.5 m free; docs/simulation.md, issue 28)."""
    return cfg.graph.anchor_start == "always" or (cfg.graph.anchor_start == "with_wheels" and with_wheels)


def run_slam(sweeps: Iterable[Sweep | PreparedSweep], imu: ImuSeries | None, cfg: SlamConfig, *,
             sensor_to_imu: np.ndarray | None = None, gnss: GnssSeries | None = None,
             antenna_in_sensor: np.ndarray | None = None, wheel: WheelTrack | None = None,
             base_to_sensor: np.ndarray | None = None, progress: Callable[[int], None] | None = None,
             warmup_ms: dict[str, float] | None = None, workers: int = 1) -> SlamOutput:
    """Replay the SLAM over `sweeps` (LiDAR frame; each prepared ahead, slam/sweep_prep.py, or prepared
    here in line: the same arrays either way). `sensor_to_imu` is the IMU pose in the LiDAR
    frame from /tf_static (the config's extrinsics override it); `gnss` in ENU enables GNSS factors;
    `wheel` (odom -> base_link, with `base_to_sensor` the LiDAR pose in base_link) enables wheel
    factors when slam.wheel_odom.enabled. The stages are warmed first (slam/warmup.py; `warmup_ms`
    given: the caller did it, before its reader thread started): their one-off cost is reported as
    `warmup_ms`, outside the per-sweep timing and `wall_s`. `workers`: threads of the offset re-match."""
    warmup_ms = warm_up(cfg) if warmup_ms is None else warmup_ms
    wall0 = time.perf_counter()
    with_wheels = wheel is not None and cfg.wheel_odom.enabled
    anchored = start_anchored(cfg, with_wheels)
    replay = _Replay.start(imu, cfg, sensor_to_imu, gnss, antenna_in_sensor, anchored)
    replay.workers = workers
    if replay.odom is not None:  # GNSS/INS: the fixes into graph #2
        replay.ins = gnss_ins.build(gnss, cfg.gps, antenna_in_sensor, base_to_sensor, with_wheels)
    if replay.ins is None:
        replay.gnss_track = build_gnss_track(gnss, cfg.gps, antenna_in_sensor, base_to_sensor, with_wheels)
    if wheel is not None and with_wheels:
        replay.wheel = wheel
        replay.base_to_sensor = np.eye(4) if base_to_sensor is None else base_to_sensor
        if replay.aligner is not None:
            replay.aligner.wheels = True
        if cfg.wheel_odom.calibration.enabled:
            replay.wheel_cal = WheelCalibrator.build(wheel, replay.imu, replay.base_to_sensor @ replay.extr,
                                                     cfg.wheel_odom.calibration)
    interval = MappingInterval(interval_s=cfg.mapping_interval_s)
    n_sweeps = n_empty = 0
    t_read, c_read = time.perf_counter(), time.thread_time()
    for item in sweeps:
        stamp = item.stamp
        n_sweeps += 1
        if progress is not None:
            progress(n_sweeps)
        if (item.n_points if isinstance(item, PreparedSweep) else len(item)) == 0:
            n_empty += 1  # nothing to map: counted, so the result says so
            continue
        if not interval.take(stamp):
            continue  # mappingProcessInterval
        replay.timing["read"].append((time.perf_counter() - t_read) * 1e3)
        replay.cpu["read"].append((time.thread_time() - c_read) * 1e3)
        replay.calibrate_wheels(stamp)
        replay.map_sweep(item if isinstance(item, PreparedSweep) else prepare_sweep(item, cfg))
        t_read, c_read = time.perf_counter(), time.thread_time()
    health = wheel_health(replay.wheel_cal, replay.wheel_gnss_scale()) if replay.wheel_cal is not None else None
    return replace(replay.output(n_sweeps, wall0), warmup_ms=warmup_ms, empty_sweeps=n_empty, wheel_health=health)


@dataclass(kw_only=True)
class _State:
    """What the replay carries from one mapped sweep to the next."""

    pose: np.ndarray | None = None
    t: float = 0.0  # stamp of `pose`, s (meaningful once pose is set)
    velocity: np.ndarray | None = None  # world frame, m/s
    last_loop_t: float = -np.inf
    loose: np.ndarray | None = None  # directions the latest match left to the IMU ([rot, trans], map axes)
    guess_by_wheels: bool = False  # the current sweep's guess took x, y and yaw from the wheels
    about_base: bool = False  # ... for the base, and scan-to-map turns about it (wheel_odom.pivot_max_gap_s)
    warned: set[str] = field(default_factory=set)


@dataclass(kw_only=True)
class _Trace:
    """Per mapped sweep: its stamp, the keyframe it hangs from and its pose relative to it (so a
    loop closure that moves the keyframe moves the sweep too), and whether matching was degenerate."""

    stamps: list[float] = field(default_factory=list)
    ref_kf: list[int] = field(default_factory=list)
    rel_to_kf: list[np.ndarray] = field(default_factory=list)
    degenerate: list[bool] = field(default_factory=list)
    online: list[np.ndarray] = field(default_factory=list)  # the pose as estimated when the sweep was processed
    measured: list[bool] = field(default_factory=list)  # scan-to-map ran and was not degenerate


@dataclass(kw_only=True)
class _OffsetRefinement:
    """The IMU-LiDAR offset applied during the run (slam.imu.refine_time_offset_s): `applied` s
    subtracted from the IMU stamps (on top of slam.imu.time_offset_s) since the sweep `start` of
    the trace, and each estimate as (stamp, estimate s)."""

    applied: float = 0.0
    start: int = 0
    history: list[tuple[float, float]] = field(default_factory=list)


@dataclass(kw_only=True)
class _Replay:
    """The replay's components and state; `map_sweep` is one pass of LIO-SAM's mapping."""

    cfg: SlamConfig
    extr: np.ndarray  # IMU pose in the LiDAR frame
    imu: ImuSeries | None
    track: ImuTrack | None
    odom: ImuOdometry | None
    graph: KeyframeGraph
    aligner: GnssAligner | None
    timing: dict[str, list[float]]
    warnings: list[str]
    cpu: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in STAGES})  # this thread's, ms
    loop_cpu_ms: float = 0.0  # CPU time of the current sweep's loop closure, ms
    events: list[SlamEvent] = field(default_factory=list)
    kf_features: list[Features] = field(default_factory=list)
    map_cache: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    local_map: LocalMap | None = None
    st: _State = field(default_factory=_State)
    trace: _Trace = field(default_factory=_Trace)
    wheel: WheelTrack | None = None
    base_to_sensor: np.ndarray = field(default_factory=lambda: np.eye(4))
    gyro_bias: np.ndarray | None = None  # subtracted from the gyro in the track (slam.gyro_bias_init_s), rad/s
    imu_noise: ImuNoiseEstimate | None = None  # from the log's stationary stretches, IMU axes
    imu_start_bias: StandingStartBias | None = None  # without those: a shorter standing start's gyro bias
    offset: _OffsetRefinement = field(default_factory=_OffsetRefinement)
    offset_cpu_ms: float = 0.0  # CPU time of the offset's re-match after the run, ms
    offset_sweeps: SweepStore = field(default_factory=lambda: SweepStore(max_sweeps=0))  # set in start()
    workers: int = 1  # threads for the offset re-match after the run (run_slam)
    wheel_cal: WheelCalibrator | None = None  # online calibration; `wheel` is then its calibrated track
    wheel_flagged: bool = False  # the wheel_health event was raised
    wheel_cal_state: tuple[int, float] | None = None  # (bins consumed, scale information) last applied
    ins: gnss_ins.GnssIns | None = None  # GNSS/INS in graph #2; graph #1 then gets no GNSS factors
    gnss_track: GnssTrack | None = None  # x, y by the fixes where the match is degenerate (no wheels)
    gate_streak: int = 0  # sweeps in a row whose match the rotation gate turned down (gate_rotation)

    @classmethod
    def start(cls, imu: ImuSeries | None, cfg: SlamConfig, sensor_to_imu: np.ndarray | None,
              gnss: GnssSeries | None, antenna_in_sensor: np.ndarray | None, anchored: bool) -> _Replay:
        warnings: list[str] = []
        extr = lidar_to_imu(cfg.imu, sensor_to_imu)
        if imu is not None and cfg.imu.time_offset_s != 0.0:  # a known IMU clock lag, before anything else
            imu = replace(imu, stamps=imu.stamps - cfg.imu.time_offset_s)
        noise, start_bias = None, None
        if imu is not None and imu.stamps.size >= 3:
            clean = clean_imu(imu)
            noise = estimate_imu_noise(clean.stamps, clean.acc, clean.gyro, gravity=cfg.imu.gravity,
                                       min_s=cfg.imu.stationary_min_s)
            if noise is None and cfg.imu.standing_start_min_s > 0:
                start_bias = standing_start_bias(clean.stamps, clean.acc, clean.gyro,
                                                 min_s=cfg.imu.standing_start_min_s,
                                                 max_rate=cfg.imu.standing_start_max_rate_rad_s)
        track, odom, imu, bias = _imu_setup(imu, extr, cfg, warnings, noise, start_bias)
        use_gnss = gnss is not None and cfg.gps.enabled and gnss.stamps.size > 0
        aligner = GnssAligner(gnss, cfg.gps, antenna_in_sensor) if use_gnss and gnss is not None else None
        if aligner is not None and cfg.gps.use_elevation and cfg.gps.gate == "residual":
            # it was set in vain on the open line (identical runs): heights would hold the map level, while
            # the line's z is the base's mount pitch (docs/simulation.md, "holding the line's z")
            warnings.append("slam.gps.use_elevation is for the lio_sam gate: the residual gate's GNSS factors "
                            "keep the chain's own z")
        graph = KeyframeGraph(cfg=cfg.graph, anchored=anchored)
        return cls(cfg=cfg, extr=extr, imu=imu, track=track, odom=odom, graph=graph, aligner=aligner,
                   timing={s: [] for s in STAGES}, warnings=warnings, gyro_bias=bias, imu_noise=noise,
                   imu_start_bias=start_bias,
                   offset_sweeps=SweepStore(max_sweeps=cfg.imu.time_offset_rematch_max_sweeps,
                                             max_points=cfg.imu.time_offset_rematch_max_points))

    # ---- one mapped sweep
    def map_sweep(self, prep: PreparedSweep) -> None:
        """Deskew the prepared range image -> features -> scan-to-map -> keyframe -> bookkeeping."""
        clock = _Clock(self.timing, self.cpu)
        self.timing["projection"].append(prep.ms)
        self.cpu["projection"].append(prep.cpu_ms)
        stamp, image = prep.stamp, prep.image
        points = self.deskew(image, stamp)
        clock.lap("deskew")
        feats = extract_features(image, points, self.cfg.features, labels=prep.labels, vertical=prep.vertical)
        clock.lap("features")
        pose, degenerate = self.scan_to_map(stamp, feats)
        clock.lap("matching")
        loop_ms = 0.0
        self.loop_cpu_ms = 0.0
        if _is_keyframe(self.graph, pose, self.cfg):
            pose, loop_ms = self.add_keyframe(pose, stamp, feats)
        clock.lap("graph", minus_ms=loop_ms, minus_cpu_ms=self.loop_cpu_ms)
        self.timing["loop"].append(loop_ms)
        self.cpu["loop"].append(self.loop_cpu_ms)
        self.record(stamp, pose, degenerate)
        if self.cfg.imu.estimate_time_offset and self.cfg.imu.time_offset_from == "rematch" and self.track is not None:
            self.offset_sweeps.add(len(self.trace.stamps) - 1, stamp, _compact(feats))
        self.refine_offset(stamp)

    def deskew(self, image: RangeImage, stamp: float) -> np.ndarray:
        """Points at the sweep stamp: rotation from the IMU track, translation at constant velocity."""
        st, cfg = self.st, self.cfg
        if image.point_time is None:
            self.warn_once(stamp, "no_time", "sweeps have no per-point time: processed without deskew "
                           "(the trajectory will drift with fast rotation)")
            return image.points
        t_end = stamp + float(image.point_time.max(initial=0.0))
        if self.track is not None and not self.track.covers(stamp, t_end):
            self.warn_once(stamp, "no_cover", f"IMU does not cover the sweep at {stamp:.3f} s: "
                           "rotation deskew clamped to the IMU span")
        v_sensor = a_sensor = None
        odom, track = self.odom, self.track
        if cfg.deskew_translation and cfg.imu.deskew_motion == "predicted" and odom is not None and track is not None \
                and odom.can_predict and st.pose is not None and track.covers(st.t, t_end) and t_end > stamp:
            # graph #2's velocity at the sweep's start and end (a rocking mast changes it within 0.1 s)
            rots, vels = odom.predict_velocity(st.pose, st.t, np.array([stamp, t_end]))
            v_sensor = rots[0].T @ vels[0]
            a_sensor = rots[0].T @ (vels[1] - vels[0]) / (t_end - stamp)
        elif cfg.deskew_translation and st.velocity is not None and st.pose is not None:
            v_sensor = st.pose[:3, :3].T @ st.velocity
        return deskew(image.points, image.point_time, stamp, self.track, v_sensor, a_sensor)

    def scan_to_map(self, stamp: float, feats: Features) -> tuple[np.ndarray, bool]:
        """Guess -> match against the local map -> roll/pitch blend -> correct graph #2.
        Returns the pose and whether matching was degenerate."""
        pose = self.guess(stamp)
        res: MatchResult | None = None
        if self.local_map is not None:
            res = match(feats.edges, feats.surfs, self.local_map, pose, self.cfg.matching, self.guess_prior(),
                        self.match_pivot())
            self.events += _match_events(res, stamp, self.cfg)
            if self.track is not None:
                res = self.gate_rotation(res, pose, stamp)
            pose = _imu_attitude_blend(res.pose, self.imu, self.extr, stamp, self.cfg)
        degenerate = bool(res is not None and res.degenerate)
        self.trace.measured.append(bool(res is not None and res.optimised and not res.degenerate))
        # the directions the IMU carries; no match (too few features, a rejected turn): all six
        unmatched = res is not None and not res.optimised
        self.st.loose = np.eye(6) if unmatched else res.degenerate_directions if degenerate and res else None
        pose = self.pose_by_fixes(pose, stamp)
        if self.odom is not None:
            why = self.odom.add_lidar_pose(pose, stamp, degenerate or unmatched, self.st.loose)
            if why:
                self.events.append(SlamEvent(t=stamp, kind="warning", message=why))
            if self.ins is not None:
                pose = gnss_ins.step(self.ins, self.odom, pose, stamp, self.events)
        return pose, degenerate

    def pose_by_fixes(self, pose: np.ndarray, stamp: float) -> np.ndarray:
        """slam/gnss_track.py: the translation the match left free, from the fixes (no wheels). At the
        first degenerate sweep after the alignment graph #2 restarts there with the track's velocity
        (it dead-reckoned until then; its velocity would fight the new positions)."""
        track = self.gnss_track
        if track is None:
            return pose
        antenna_xy = track.antenna_xy(stamp, pose)
        if antenna_xy is None or self.st.loose is None:
            return pose
        if not track.engaged or (track.ins.alignment is not None and not track.engaged_final):
            self.engage_track(track, stamp)
        return move_along_free(pose, track.ins.antenna_in_lidar, antenna_xy, self.st.loose, both_axes=track.both_axes)

    def engage_track(self, track: GnssTrack, stamp: float) -> None:
        """The track takes over x, y (on the provisional alignment, or the final one), or moves from the
        provisional to the final alignment: an event, and graph #2 restarts with the track's velocity
        (it dead-reckoned until then, or moved on the provisional alignment's yaw)."""
        final = track.ins.alignment is not None
        what = "engaged" if not track.engaged else "realigned"
        track.engaged, track.engaged_final = True, final
        align = track.alignment()
        self.events.append(SlamEvent(t=stamp, kind="gps", message=f"GNSS track {what}: x, y along the directions "
                                     "scan-to-map leaves free follow the fixes from here (ENU -> map alignment from "
                                     f"the fixes' course, {'final' if final else 'provisional'})",
                                     data={"gnss_track": what, "enu_to_map_yaw_deg":
                                           float(np.degrees(align.yaw_rad)) if align is not None else None}))
        if self.odom is not None and self.odom.can_predict:
            self.odom.restart()
            self.odom.velocity = np.r_[track.velocity_map(stamp), self.odom.velocity[2]]

    def guess_prior(self) -> np.ndarray | None:
        """Information (J^T J's units) holding the matched yaw towards a wheel guess: over one sweep the
        wheels' yaw increment is good to a few hundredths of a degree on a straight drive, while the
        yaw a few far poles give jumps by a degree from sweep to sweep; None without a wheel guess."""
        info = self.cfg.wheel_odom.yaw_information
        if not self.st.guess_by_wheels or info <= 0:
            return None
        if self.wheel_cal is not None:  # scaled by the measured wheel quality
            info *= self.wheel_cal.yaw_quality()
        return np.array([0.0, 0.0, info, 0.0, 0.0, 0.0])

    def calibrate_wheels(self, t: float) -> None:
        """Consume the wheel increments up to t into the online calibration, take its calibrated
        track, and raise one wheel_health event when the wheels first disagree."""
        cal = self.wheel_cal
        if cal is None:
            return
        cal.update(t)
        state = (cal.next_bin, len(cal.steps_lidar_m))  # the track and the health change only with these
        if state == self.wheel_cal_state:
            return
        self.wheel_cal_state = state
        self.wheel = cal.track()
        if self.wheel_flagged or cal.n_bins < cal.cfg.warmup_bins:
            return
        health = wheel_health(cal)
        if health["verdict"] != "ok":
            self.wheel_flagged = True
            self.events.append(SlamEvent(t=t, kind="wheel_health", message=f"wheel odometry {health['verdict']}: "
                                         + "; ".join(health["reasons"]) + " (calibrated online)",
                                         data={k: v for k, v in health.items() if isinstance(v, float)}))

    def wheel_gnss_scale(self) -> GnssScale | None:
        """The wheels' scale from the fixes against the calibrated wheel track (slam/wheel_gnss_scale.py),
        for wheel_health when no LiDAR step measured it; None without GNSS in use."""
        cal, span = self.wheel_cal, self.cfg.wheel_odom.calibration.gnss_scale_min_span_m
        if cal is None or self.aligner is None or span <= 0 or (cal.scale_fit is not None and cal.scale_fit.steps):
            return None
        return gnss_scale(cal.track(), self.aligner.gnss, max_var_m2=self.cfg.gps.gps_cov_threshold_m2,
                          min_span_m=span, correlation_s=self.cfg.wheel_odom.calibration.gnss_scale_correlation_s,
                          track=track_filter(self.cfg.gps))

    def match_pivot(self) -> np.ndarray | None:
        """The base origin in the sensor frame when the wheels placed the base (wheel_guess): scan-to-map
        then turns about it, so the x and y it holds are the base's."""
        return np.asarray(se3.inv(self.base_to_sensor)[:3, 3], np.float64) if self.st.about_base else None

    def gate_rotation(self, res: MatchResult, guess: np.ndarray, stamp: float) -> MatchResult:
        """A match that turns the gyro-predicted attitude by more than max_rotation_correction_deg
        is a false match (sparse structure, wrong neighbours: in an open field up to 30 deg in one
        sweep), not a gyro error: keep the IMU guess, as for a sweep without features. From the
        tilt_after_rejections-th such sweep in a row, a match whose tilt is within
        max_tilt_correction_deg keeps its roll, pitch and z (the turn was yaw; the guess's tilt
        would drift and z walk, docs/simulation.md "the rotation gate's z walk")."""
        limit = self.cfg.matching.max_rotation_correction_deg
        if self.wheel is not None and self.cfg.wheel_odom.guess and self.cfg.wheel_odom.max_rotation_correction_deg > 0:
            limit = self.cfg.wheel_odom.max_rotation_correction_deg  # a better guess may take a tighter gate
        turn = np.degrees(se3.delta_angle(se3.inv(guess) @ res.pose))
        if not res.optimised or limit <= 0:
            return res
        if turn <= limit:
            self.gate_streak = 0
            return res
        self.gate_streak += 1
        tilt = tilt_correction_deg(res, guess)
        if tilt <= self.cfg.matching.max_tilt_correction_deg \
                and self.gate_streak >= self.cfg.matching.tilt_after_rejections:  # the turn is yaw: keep the ground's
            self.events.append(SlamEvent(t=stamp, kind="warning",
                                         message=f"scan-to-map turned the IMU attitude by {turn:.1f} deg (limit "
                                                 f"{limit:g}), its tilt by {tilt:.1f} deg: kept its roll, pitch "
                                                 "and z, the IMU's yaw, x and y",
                                         data={"correction_deg": turn, "tilt_correction_deg": tilt}))
            return keep_tilt(res, guess)
        self.events.append(SlamEvent(t=stamp, kind="warning",
                                     message=f"scan-to-map turned the IMU attitude by {turn:.1f} deg "
                                             f"(limit {limit:g}): rejected, kept the IMU guess",
                                     data={"correction_deg": turn, "tilt_correction_deg": tilt}))
        return replace(res, pose=guess, optimised=False, degenerate=False, degenerate_directions=None)

    def guess(self, t: float) -> np.ndarray:
        """Initial pose: IMU attitude for the first sweep; then graph #2's prediction, else the IMU
        rotation increment with constant velocity, else constant velocity."""
        st, track, odom = self.st, self.track, self.odom
        st.guess_by_wheels = st.about_base = False
        if st.pose is None:
            att, velocity = self.first_state(t)
            if velocity is not None and odom is not None:  # graph #2 starts at the wheels' speed, not at rest
                odom.velocity = att @ velocity
            return se3.make(att, np.zeros(3))
        covered = track is not None and track.covers(st.t, t)
        if odom is not None and covered and odom.can_predict:  # also right after a loop restarted graph #2
            return self.wheel_guess(odom.predict(st.pose, st.t, t), t)
        step = (st.velocity if st.velocity is not None else np.zeros(3)) * (t - st.t)
        rot = st.pose[:3, :3]
        if covered and track is not None:
            rot = rot @ track.rotation_between(st.t, np.array([t]))[0]
        return se3.make(rot, st.pose[:3, 3] + step)

    def first_state(self, t: float) -> tuple[np.ndarray, np.ndarray | None]:
        """The LiDAR's roll/pitch at the first sweep (yaw 0) and, when driving, the IMU's velocity
        then (m/s, LiDAR axes; else None). The attitude: the IMU's orientation, or its accelerometer
        about t (initial_attitude); a 6-axis IMU on a machine the wheels show already driving (a log
        begun mid-drive) over attitude_driving_window_s instead, with the IMU's velocity change
        (driving_attitude). A standing start keeps the 0.1 s look-ahead: start-up acceleration.
        Without wheels nothing says whether the machine drives: the window's mean with no velocity
        change (steady driving) replaces the look-ahead when the two tilts differ by more than a
        start-up acceleration can (imu.bumpy_start_attitude): the look-ahead then read bumps."""
        if self.imu is None:
            return np.eye(3), None
        att = initial_attitude(self.imu, self.extr[:3, :3], self.cfg.imu, t)
        if self.track is None or self.imu.orientation_xyzw is not None:
            return att, None
        t_imu = max(t, float(self.track.stamps[0]))  # a log cut mid-drive: its first sample can follow the sweep
        window = self.cfg.imu.attitude_driving_window_s
        v = self.driving_velocities(t_imu, window) if t_imu - t <= 0.2 else None  # s: one wheel bin
        driving = None if v is None else driving_attitude(self.track, t_imu, window, v[1] - v[0])
        if driving is None and self.wheel is None and window > 0.4:
            standing = None if self.imu_noise is None else self.imu_noise.gyro_sample_std
            steady = bumpy_start_attitude(att, self.track, t_imu, window, standing_gyro_std=standing)
            if steady is not None:
                return steady, None
        return (att, None) if driving is None or v is None else (driving, v[0])

    def driving_velocities(self, t: float, window_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The IMU's velocity at t and at t + window_s (m/s, both in LiDAR axes at t): the base's by the
        wheels, each the mean over 0.2 s (the calibrator's standing-start bin) from that end inwards,
        plus w x r, the IMU's lever r from base_link turning at the gyro's rate w (the wheels see the
        base only; a machine rocking on rough ground swings an IMU 1 m up by a metre per second). None
        unless the wheels and the IMU cover the window (from the wheels' first sample when it follows
        t) and the first speed exceeds the standing-start limit."""
        wheel, track, h = self.wheel, self.track, 0.2  # s
        if wheel is None or track is None or wheel.stamps.size < 2:
            return None
        t = max(t, float(wheel.stamps[0]))  # a log cut mid-drive: its first wheel sample can follow the sweep
        t1 = t + window_s
        if window_s <= 2 * h or not wheel.covers(t, t1) or not track.covers(t, t1):
            return None
        p = np.array([wheel.pose_at(x)[:3, 3] for x in (t, t + h, t1 - h, t1)])
        v0, v1 = (p[1] - p[0]) / h, (p[3] - p[2]) / h  # odom axes
        if np.linalg.norm(v0[:2]) <= self.cfg.wheel_odom.calibration.stationary_speed_mps:
            return None
        r_bs, t_bs = self.base_to_sensor[:3, :3], self.base_to_sensor[:3, 3]
        lever = self.extr[:3, 3] + r_bs.T @ t_bs  # IMU from base_link, LiDAR axes
        w0, w1 = (track.gyro[(track.stamps >= a) & (track.stamps < a + h)].mean(axis=0) for a in (t, t1 - h))
        turn = track.rotation_between(t, np.array([t1 - 0.5 * h]))[0]
        to_lidar = (wheel.pose_at(t)[:3, :3] @ r_bs).T
        return to_lidar @ v0 + np.cross(w0, lever), to_lidar @ v1 + turn @ np.cross(w1, lever)

    def wheel_guess(self, predicted: np.ndarray, t: float) -> np.ndarray:
        """With slam.wheel_odom.guess: x, y and yaw of the base from the wheels' motion since the
        last pose, its z, roll and pitch from graph #2 (a straight, slip-free drive carries no gyro or
        accelerometer bias; scan-to-map keeps the guess along the directions bare ground leaves free)."""
        if self.wheel is None or not self.cfg.wheel_odom.guess or not self.wheel.covers(self.st.t, t) \
                or self.st.pose is None:
            return predicted
        by_wheels = self.st.pose @ relative_motion(self.wheel, self.st.t, t, self.base_to_sensor)
        self.st.guess_by_wheels = True
        # as the base (the sensor on its mast sways with roll and pitch), when the last mapped sweep is
        # recent: over the 1 s gaps of throttled logs graph #2's guess can be metres off, and steps
        # turning about a point 2 m away diverged there (sample loop_forest: 0.47 m)
        self.st.about_base = t - self.st.t <= self.cfg.wheel_odom.pivot_max_gap_s
        if not self.st.about_base:
            return blend_planar(predicted, by_wheels)
        to_base = se3.inv(self.base_to_sensor)
        return np.asarray(blend_planar(predicted @ to_base, by_wheels @ to_base) @ self.base_to_sensor, np.float64)

    def add_keyframe(self, pose: np.ndarray, stamp: float, feats: Features) -> tuple[np.ndarray, float]:
        """Graph #1 keyframe, GNSS factor, loop closure (timed apart), new local map.
        Returns the optimised pose and the loop-closure time (ms)."""
        wheel = None
        if self.wheel is not None and self.graph.stamps:
            wheel = wheel_factor(self.wheel, self.graph.stamps[-1], stamp, self.base_to_sensor, self.cfg.wheel_odom)
        if wheel is not None and self.wheel_cal is not None and self.trace.stamps:
            self.fit_wheel_scale(pose, stamp)
        self.graph.add_keyframe(pose, stamp, self.st.loose, wheel, self.cfg.wheel_odom.lidar_degenerate_sigma)
        if wheel is not None:
            self.restart_from_wheels(pose, stamp)
        self.kf_features.append(_compact(feats))
        if self.aligner is not None and self.ins is None and not (self.gnss_track and self.gnss_track.engaged) \
                and self.aligner.maybe_add(self.graph, stamp, self.events):
            self.map_cache.clear()
            moved = float(np.linalg.norm(self.graph.poses[-1][:3, 3] - pose[:3, 3]))
            if self.odom is not None and (self.cfg.gps.rtk_max_variance_m2 > 0 or self.cfg.gps.gate == "residual") \
                    and moved > self.cfg.imu.restart_after_loop_m:
                self.odom.restart()  # RTK fixes move the pose by decimetres: graph #2 restarts as after a loop
                if self.aligner.velocity_error is not None and self.wheel is None \
                        and self.cfg.gps.residual_velocity_correction:  # the fixes' drift rate
                    self.odom.velocity = self.odom.velocity + np.r_[self.aligner.velocity_error, 0.0]
        loop_ms = self.loop_cpu_ms = 0.0
        if self.cfg.loop.enabled and stamp - self.st.last_loop_t >= self.cfg.loop.interval_s:
            self.st.last_loop_t = stamp
            t0, c0 = time.perf_counter(), time.thread_time()
            self.close_loop(stamp)
            loop_ms, self.loop_cpu_ms = (time.perf_counter() - t0) * 1e3, (time.thread_time() - c0) * 1e3
        self.local_map = _local_map(self.graph, self.kf_features, self.map_cache, self.cfg)
        return self.graph.poses[-1], loop_ms

    def fit_wheel_scale(self, pose: np.ndarray, stamp: float) -> None:
        """Wheel vs LiDAR distance since the last keyframe, when every sweep since it was matched
        without a degenerate direction (the LiDAR pinned the forward motion) and the base drove
        straight (the rolling radius, not the slip of a turn)."""
        cal, tr, t0 = self.wheel_cal, self.trace, self.graph.stamps[-1]
        since = [m for t, m in zip(tr.stamps, tr.measured, strict=False) if t > t0]
        if cal is None or not since or not all(since) or not tr.measured[-1]:
            return
        rel_base = self.base_to_sensor @ se3.inv(self.graph.poses[-1]) @ pose @ se3.inv(self.base_to_sensor)
        if abs(se3.rpy(rel_base)[2]) > cal.cfg.scale_max_turn_rad:
            return  # turning: a skid-steer's tracks slip and over-read (slip on wet ground: fit_scale's gate)
        lidar = float(np.linalg.norm(rel_base[:2, 3]))
        i0, i1 = np.searchsorted(cal.inc.stamps, [t0, stamp])
        cal.add_distance(float(np.abs(cal.inc.forward_m[i0:i1]).sum()), lidar)

    def restart_from_wheels(self, matched: np.ndarray, stamp: float) -> None:
        """When the wheel factor moved the keyframe, graph #2 restarts from graph #1's pose (as after
        a loop) with the wheels' velocity: graph #2 otherwise keeps integrating its own velocity and
        attitude, and the next guess contradicts the corrected pose."""
        kf = self.graph.poses[-1]
        moved = float(np.linalg.norm(kf[:3, 3] - matched[:3, 3]))
        if self.odom is None or self.wheel is None or moved <= self.cfg.wheel_odom.restart_imu_after_m:
            return
        v_base = base_velocity(self.wheel, stamp)
        self.odom.restart()
        if v_base is not None:  # base_link axes -> map: R_map_lidar R_lidar_base
            self.odom.velocity = kf[:3, :3] @ self.base_to_sensor[:3, :3].T @ v_base

    def close_loop(self, stamp: float) -> None:
        moved = _try_loop(self.graph, self.kf_features, self.cfg, self.events, stamp)
        if moved is not None:
            self.map_cache.clear()
            if self.odom is not None and moved > self.cfg.imu.restart_after_loop_m:
                self.odom.restart()  # the global pose jumped: graph #2 restarts from it

    def record(self, stamp: float, pose: np.ndarray, degenerate: bool) -> None:
        """Keep the sweep relative to the latest keyframe; update the motion state."""
        st, tr = self.st, self.trace
        k_ref = len(self.graph.poses) - 1
        tr.stamps.append(stamp)
        tr.ref_kf.append(k_ref)
        tr.rel_to_kf.append(se3.inv(self.graph.poses[k_ref]) @ pose)
        tr.degenerate.append(degenerate)
        tr.online.append(pose)
        if self.odom is not None:
            st.velocity = self.odom.velocity.copy()
        elif st.pose is not None and stamp > st.t:
            st.velocity = (pose[:3, 3] - st.pose[:3, 3]) / (stamp - st.t)
        st.pose, st.t = pose, stamp

    def refine_offset(self, stamp: float) -> None:
        """Every slam.imu.refine_time_offset_s: estimate the IMU-LiDAR offset left in every sweep so
        far against the IMU as now stamped, and shift the IMU stamps by it from now on. The matched
        poses keep part of the IMU-driven guess, so one estimate reads only part of a large lag (30 ms
        -> 23-28 ms); applied, the poses that follow keep less of it. An estimate at the search
        bound is not trusted."""
        every, tr, off = self.cfg.imu.refine_time_offset_s, self.trace, self.offset
        if every <= 0 or not self.cfg.imu.estimate_time_offset or self.track is None or self.imu is None \
                or stamp - tr.stamps[off.start] < every:
            return
        off.start = len(tr.stamps) - 1  # the next estimate after another `every` s
        found = self.segment_offset()
        # applied only when it stands out of its own noise (2 standard errors) and inside the search
        if found is None or abs(found.offset_s) >= SEARCH_S - 1e-3 or abs(found.offset_s) < 2 * found.sigma_s:
            return
        est = found.offset_s
        off.history.append((stamp, est))
        off.applied += est
        self.imu = replace(self.imu, stamps=self.imu.stamps - est)
        if self.wheel_cal is not None:
            self.wheel_cal.restamp_gyro(est)
        self.track = imu_track(self.imu, self.extr[:3, :3], self.gyro_bias, self.cfg.imu.sample_hold)
        if self.odom is not None:
            self.odom.track = self.track
        self.events.append(SlamEvent(t=stamp, kind="imu_time_offset",
                                     message=f"IMU-LiDAR offset {est * 1e3:+.1f} ms since the last estimate: "
                                     f"applied, {off.applied * 1e3:.1f} ms in all",
                                     data={"estimate_s": est, "applied_s": off.applied}))

    def segment_offset(self, k: int = 0) -> OffsetEstimate | None:
        """The offset left in the sweeps from the k-th on against the IMU as now stamped (None: too few
        or no rotation)."""
        tr = self.trace
        if self.track is None or len(tr.stamps) - k < 2:
            return None
        online = np.array(tr.online[k:])
        return imu_time_offset(np.asarray(tr.stamps[k:]), online[:, :3, :3], self.track,
                               np.asarray(tr.measured[k:], bool))

    def rematch_offset(self, stamps: np.ndarray, poses: np.ndarray) -> OffsetEstimate | None:
        """slam.imu.time_offset_from=rematch: the offset from the sweeps matched again after the run
        (slam/offset_rematch.py), against the IMU as now stamped; timed as the "offset" stage."""
        if self.track is None:
            return None
        c0 = time.process_time()  # the re-match's worker threads included (the reader is done by now)
        run = RunForOffset(stamps=stamps, poses=poses, feats=self.offset_sweeps.feats,
                           kf_stamps=np.asarray(self.graph.stamps, np.float64),
                           kf_poses=np.array(self.graph.poses), kf_feats=self.kf_features)
        found = rematch_time_offset(run, self.track, self.cfg.matching, np.asarray(self.trace.measured, bool),
                                    self.workers)
        self.offset_cpu_ms = (time.process_time() - c0) * 1e3
        return found

    def warn_once(self, t: float, key: str, text: str) -> None:
        """A condition that holds for the whole log: one warning (and one event at its first sweep)."""
        if key not in self.st.warned:
            self.st.warned.add(key)
            self.warnings.append(text)
            self.events.append(SlamEvent(t=t, kind="warning", message=text))

    # ---- the end
    def output(self, n_sweeps: int, wall0: float) -> SlamOutput:
        """Sweep poses re-anchored to their final keyframes, the map from every keyframe's features."""
        tr = self.trace
        kf_poses = np.array(self.graph.poses) if self.graph.poses else np.zeros((0, 4, 4))
        poses = np.zeros((0, 4, 4))
        if tr.stamps:
            poses = np.array([kf_poses[k] @ r for k, r in zip(tr.ref_kf, tr.rel_to_kf, strict=True)])
        map_points, quality = np.zeros((0, 3)), None
        if self.kf_features:
            dense = np.vstack([_keyframe_cloud(self.graph, self.kf_features, i)
                               for i in range(len(self.kf_features))])
            map_points = voxel_downsample(dense, self.cfg.matching.surf_leaf_m)
            quality = self.map_quality(dense)
        stamps = np.asarray(tr.stamps)
        online = np.array(tr.online) if tr.online else np.zeros((0, 4, 4))
        offset = sigma = None
        if self.track is not None and self.cfg.imu.estimate_time_offset and stamps.size > 1:
            # what the applied estimates left (all of it when none was applied)
            left = self.rematch_offset(stamps, poses) if self.offset_sweeps.feats else self.segment_offset()
            if left is not None:
                offset, sigma = self.offset.applied + left.offset_s, left.sigma_s
            elif self.offset.history:
                offset = self.offset.applied
        return SlamOutput(stamps=stamps, poses=poses, kf_stamps=np.asarray(self.graph.stamps), kf_poses=kf_poses,
                          map_points=map_points, timing_ms=self.timing, cpu_ms=self.cpu, events=self.events,
                          warnings=self.warnings, n_sweeps=n_sweeps, wall_s=time.perf_counter() - wall0,
                          imu_bias=self.odom.bias_vector if self.odom is not None else None,
                          degenerate=np.asarray(tr.degenerate, bool), online_poses=online,
                          imu_time_offset_s=offset, map_quality=quality, imu_noise=self.imu_report(),
                          imu_time_offset_sigma_s=sigma, imu_time_offset_cpu_ms=self.offset_cpu_ms)

    def imu_report(self) -> dict[str, Any] | None:
        """The IMU's measured noise and biases (IMU axes), what the preintegration used, and how
        graph #2 restarted."""
        if self.track is None:
            return None
        out: dict[str, Any] = {"stationary": None if self.imu_noise is None else self.imu_noise.summary()}
        if self.imu_start_bias is not None:
            out["standing_start"] = self.imu_start_bias.summary()
        if self.odom is not None:
            out.update(used_from_log=bool(self.cfg.imu.noise_from_log and self.imu_noise is not None),
                       acc_noise_used=self.odom.noise_used[0], gyro_noise_used=self.odom.noise_used[1],
                       reset_priors=self.cfg.imu.reset_priors, marginal_resets=self.odom.marginal_resets,
                       failure_resets=self.odom.resets)
        return out

    def map_quality(self, dense: np.ndarray) -> MapQuality | None:
        """Entropy and plane variance of the union of keyframe clouds in their final poses."""
        mq = self.cfg.map_quality
        if not mq.enabled:
            return None
        return map_quality(dense, mq.radius_m, min_neighbours=mq.min_neighbours, max_neighbours=mq.max_neighbours,
                           max_points=mq.max_points)


class _Clock:
    """Per-stage wall time and this thread's CPU time (ms) of one sweep."""

    def __init__(self, timing: dict[str, list[float]], cpu: dict[str, list[float]]) -> None:
        self.timing, self.cpu = timing, cpu
        self.t, self.c = time.perf_counter(), time.thread_time()

    def lap(self, stage: str, minus_ms: float = 0.0, minus_cpu_ms: float = 0.0) -> None:
        now, cpu = time.perf_counter(), time.thread_time()
        self.timing[stage].append((now - self.t) * 1e3 - minus_ms)
        self.cpu[stage].append((cpu - self.c) * 1e3 - minus_cpu_ms)
        self.t, self.c = now, cpu


def _imu_setup(imu: ImuSeries | None, extr: np.ndarray, cfg: SlamConfig, warnings: list[str],
               noise: ImuNoiseEstimate | None = None, start_bias: StandingStartBias | None = None
               ) -> tuple[ImuTrack | None, ImuOdometry | None, ImuSeries | None, np.ndarray | None]:
    if imu is None or imu.stamps.size < 3:
        warnings.append("no IMU: no deskew rotation, no attitude initialisation, constant-velocity guess only")
        return None, None, None, None
    imu = clean_imu(imu)
    bias = None
    if cfg.gyro_bias_init_s > 0:
        bias = imu.gyro[imu.stamps <= imu.stamps[0] + cfg.gyro_bias_init_s].mean(axis=0)
    track = imu_track(imu, extr[:3, :3], bias, cfg.imu.sample_hold)
    odom = ImuOdometry(track, cfg.imu, extr, noise, start_bias) if cfg.imu.use_preintegration_graph else None
    return track, odom, imu, bias


def _imu_attitude_blend(pose: np.ndarray, imu: ImuSeries | None, extr: np.ndarray, t: float,
                        cfg: SlamConfig) -> np.ndarray:
    """9-axis IMU only: slerp the matched roll/pitch towards the IMU's orientation by rpy_weight
    (LIO-SAM, |pitch| < 1.4 rad). A 6-axis IMU has no orientation to blend towards: unchanged."""
    if imu is None or imu.orientation_xyzw is None or cfg.imu.rpy_weight <= 0:
        return pose
    r, p, y = rotation.rpy(pose[:3, :3])
    ir, ip, _ = rotation.rpy(initial_attitude(imu, extr[:3, :3], cfg.imu, t))
    if abs(ip) >= 1.4:
        return pose
    w = cfg.imu.rpy_weight
    br, bp, _ = rotation.rpy(rotation.slerp(rotation.from_rpy([r, p, 0.0]), rotation.from_rpy([ir, ip, 0.0]), w))
    return se3.make(rotation.from_rpy([br, bp, y]), pose[:3, 3])


def _match_events(res: MatchResult, t: float, cfg: SlamConfig) -> list[SlamEvent]:
    events = []
    if res.degenerate:
        threshold = cfg.matching.degeneracy_eigen_threshold
        events.append(SlamEvent(t=t, kind="degeneracy",
                                message=f"scan-to-map degenerate: {res.n_degenerate} direction(s) with "
                                        f"eigenvalue < {threshold:g} (min {res.min_eigenvalue:.1f}); "
                                        "updates along them suppressed",
                                data={"min_eigenvalue": res.min_eigenvalue, "directions": res.n_degenerate,
                                      "weakest_direction": res.weakest_direction}))
    if not res.optimised:
        events.append(SlamEvent(t=t, kind="warning",
                                message=f"too few features ({res.n_edges} edges, {res.n_surfs} planes, "
                                        f"need {cfg.matching.min_edges}/{cfg.matching.min_surfs}): kept the IMU guess"))
    return events


def _is_keyframe(graph: KeyframeGraph, pose: np.ndarray, cfg: SlamConfig) -> bool:
    if not graph.poses:
        return True
    d = se3.inv(graph.poses[-1]) @ pose
    return bool(np.linalg.norm(d[:3, 3]) >= cfg.graph.keyframe_dist_m
                or np.any(np.abs(se3.rpy(d)) >= cfg.graph.keyframe_angle_rad))


def _local_map(graph: KeyframeGraph, feats: list[Features], cache: dict[int, tuple[np.ndarray, np.ndarray]],
               cfg: SlamConfig) -> LocalMap:
    """The keyframes of `_local_keyframes` in the map frame, voxelised into edge and plane maps. The
    map-frame clouds are cached for the keyframes of the current local map only (LIO-SAM keeps up to
    1000: all of a 10-minute run's keyframes, a second copy of every keyframe cloud); a keyframe that
    comes back into the local map is transformed again, well under a millisecond."""
    m = cfg.matching
    chosen = _local_keyframes(np.array([p[:3, 3] for p in graph.poses]), np.asarray(graph.stamps), cfg)
    for gone in set(cache) - set(chosen.tolist()):  # keep only the current local map's clouds
        del cache[gone]
    edges, surfs = [], []
    for i in chosen:
        if i not in cache:
            cache[i] = (se3.apply(graph.poses[i], feats[i].edges), se3.apply(graph.poses[i], feats[i].surfs))
        edges.append(cache[i][0])
        surfs.append(cache[i][1])
    return LocalMap.build(voxel_downsample(np.vstack(edges), m.corner_leaf_m),
                          voxel_downsample(np.vstack(surfs), m.surf_leaf_m))


def _compact(feats: Features) -> Features:
    """A keyframe's features as kept for the whole run: float32 (LIO-SAM's PCL clouds are float32
    too; 1e-6 m at 10 m), half the memory of every keyframe's feature clouds."""
    return Features(edges=feats.edges.astype(np.float32), surfs=feats.surfs.astype(np.float32))


def _local_keyframes(pos: np.ndarray, t: np.ndarray, cfg: SlamConfig) -> np.ndarray:
    """Keyframes within map_radius of the last one, thinned per keyframe_density voxel, plus every
    keyframe of the last map_recent_s. Thinning "nearest" (LIO-SAM): voxelise the positions
    (centroids) and take the keyframe nearest to each centroid; "oldest": the first keyframe in
    each voxel (this replay's earlier rule: on small loops it re-localises against the first lap)."""
    m = cfg.matching
    near = np.flatnonzero(np.linalg.norm(pos - pos[-1], axis=1) <= m.map_radius_m)
    if m.keyframe_density_m > 0 and near.size > 1:
        if m.local_map_selection == "nearest":
            centroids = voxel_downsample(pos[near], m.keyframe_density_m)
            _, nearest = KdTree(pos[near]).query(centroids, k=1)
            near = near[np.unique(nearest)]
        else:
            key = np.floor(pos[near] / m.keyframe_density_m).astype(np.int64)
            _, first = np.unique(key, axis=0, return_index=True)
            near = near[first]
    return np.union1d(near, np.flatnonzero(t >= t[-1] - m.map_recent_s))


def _keyframe_cloud(graph: KeyframeGraph, feats: list[Features], i: int) -> np.ndarray:
    """Keyframe i's edges and planes in the map frame."""
    return se3.apply(graph.poses[i], np.r_[feats[i].edges, feats[i].surfs])


def _leaves_a_direction_free(aligned_src: np.ndarray, tgt: np.ndarray, origin: np.ndarray,
                             cfg: SlamConfig) -> float | None:
    """The smallest eigenvalue of the ICP-aligned clouds' point-to-plane information when it is below
    slam.loop.min_eigenvalue (bare ground: ICP slides in x, y and yaw with a low fitness); None when
    the loop may be closed (or the gate is off)."""
    if cfg.loop.min_eigenvalue <= 0:
        return None
    eig = icp_min_eigenvalue(aligned_src, tgt, origin, cfg.matching.ground_normal_min_z)
    return eig if eig < cfg.loop.min_eigenvalue else None


def _try_loop(graph: KeyframeGraph, feats: list[Features], cfg: SlamConfig, events: list[SlamEvent],
              stamp: float) -> float | None:
    """Radius search for an old keyframe, ICP of the latest keyframe cloud onto the old one's
    submap, a loop factor when ICP converged with fitness below the threshold. Returns how far
    (m) the optimisation moved the latest keyframe, or None without a loop factor."""
    lc = cfg.loop
    prev = loop_candidate(graph, lc)
    if prev is None:
        return None
    cur = len(graph.poses) - 1
    src = voxel_downsample(_keyframe_cloud(graph, feats, cur), lc.leaf_m)
    lo, hi = max(0, prev - lc.neighbours), min(cur, prev + lc.neighbours + 1)
    tgt = voxel_downsample(np.vstack([_keyframe_cloud(graph, feats, i) for i in range(lo, hi)]), lc.leaf_m)
    if len(src) < lc.min_source_points or len(tgt) < lc.min_target_points:
        return None
    T, fitness, ok = register_loop(src, tgt, np.eye(4), lc)
    if not ok or fitness > lc.fitness_threshold_m2:
        return None
    eig = _leaves_a_direction_free(se3.apply(T, src), tgt, (T @ graph.poses[cur])[:3, 3], cfg)
    if eig is not None:
        events.append(SlamEvent(t=stamp, kind="loop_rejected",
                                message=f"loop closure {cur} -> {prev} rejected: degenerate (smallest eigenvalue "
                                        f"{eig:.1f} < {cfg.loop.min_eigenvalue:g}), fitness {fitness:.3f} m^2",
                                data={"current": cur, "previous": prev, "fitness": fitness, "min_eigenvalue": eig}))
        return None
    relative = se3.inv(graph.poses[prev]) @ (T @ graph.poses[cur])  # corrected current pose, seen from prev
    before = graph.poses[cur][:3, 3].copy()
    try:
        graph.add_loop(cur, prev, relative, fitness)
    except ProcessingError as err:
        events.append(SlamEvent(t=stamp, kind="warning",
                                message=f"loop closure {cur} -> {prev} rejected by the solver: {err}"))
        return None
    moved = float(np.linalg.norm(graph.poses[cur][:3, 3] - before))
    events.append(SlamEvent(t=stamp, kind="loop_closure",
                            message=f"keyframe {cur} -> {prev}, fitness {fitness:.3f} m^2, moved {moved:.3f} m",
                            data={"current": cur, "previous": prev, "fitness": fitness,
                                  "correction_m": float(np.linalg.norm(T[:3, 3]))}))
    return moved
