"""`mrnc-eval slam`: replay the SLAM (or the kiss-icp peer) on logs, evaluate, write results."""

from __future__ import annotations

import dataclasses
import itertools
import json
import logging
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Generator, Iterable, Iterator
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mrnc_eval.commands.gates import raise_on_failed_gates
from mrnc_eval.commands.progress import progress_bar
from mrnc_eval.commands.slam_threads import openmp_threads, run_threads
from mrnc_eval.commands.slam_wheels import clock_checked, clock_warning, read_wheel_track
from mrnc_eval.config import Config, config_hash, dump_config, replace_path
from mrnc_eval.data import GnssSeries, ImuSeries, Sweep, Trajectory
from mrnc_eval.errors import EvaluationError, InputError, NoGnssFix, UsageError
from mrnc_eval.evaluation.comparison import Cell, judge, table_one
from mrnc_eval.geometry import rotation
from mrnc_eval.io.ground_truth import ground_truth_of, ground_truth_spec
from mrnc_eval.io.prefetch import Prefetched
from mrnc_eval.io.tf_tree import StaticTransforms, static_pose
from mrnc_eval.results import (
    Event,
    Metric,
    RunResult,
    absolute_log_path,
    check_output_root,
    json_safe,
    link_latest,
    log_id_for,
    new_run_dir,
    stable_id,
    write_result,
)
from mrnc_eval.schema import slam as K
from mrnc_eval.slam.mapping_interval import MappingInterval
from mrnc_eval.slam.output import STAGES, SlamEvent, SlamOutput
from mrnc_eval.slam.wheel_odometry import WheelTrack
from mrnc_eval.text import printable

if TYPE_CHECKING:
    from mrnc_eval.evaluation.ape import ApeResult
    from mrnc_eval.io.reader import LogReader
    from mrnc_eval.slam.config import SlamConfig
    from mrnc_eval.slam.ground_mount import GroundMount
    from mrnc_eval.slam.mount_check import MountCheck
    from mrnc_eval.slam.sweep_prep import PreparedSweep
    from mrnc_eval.slam.wheel_clock import WheelClock

log = logging.getLogger(__name__)
TABLE_METRIC = {"online": "ape_online_rmse_m", "smoothed": "ape_rmse_m"}
METHODS = ("lio", "kiss-icp")
THROTTLED_GAP_PERIODS = 1.5  # kiss-icp's deskew is off when sweeps are further apart than this many periods
IMU_OFFSET_FINDING_S = 0.002  # an estimated IMU-LiDAR offset above this is reported as a health finding
# The trajectory disagrees with GNSS when its RMS distance from the fixes (yaw + translation aligned)
# exceeds both: float fixes with multipath sit 1-2 m from the truth (the sample logs' 1.8-2.0 m).
GNSS_DISAGREE_MIN_M = 5.0
GNSS_DISAGREE_SIGMAS = 10.0  # times the fixes' own median horizontal sigma


@dataclass(frozen=True, kw_only=True)
class LogInputs:
    """What the SLAM needs from a log besides the sweeps, read in the overview pass."""

    duration_s: float
    base_to_sensor: np.ndarray  # LiDAR pose in base_link (/tf_static), 4x4
    imu: ImuSeries | None
    sensor_to_imu: np.ndarray  # IMU pose in the LiDAR frame, 4x4
    gnss: GnssSeries | None
    ground_truth: Trajectory | None
    antenna: np.ndarray  # GNSS antenna in base_link, m
    antenna_in_sensor: np.ndarray  # ... in the LiDAR frame, m
    n_sweeps: int  # LiDAR messages in the log
    max_sweep_gap_s: float  # largest gap between consecutive LiDAR header stamps
    notes: tuple[str, ...] = ()  # why an input was not used (GNSS without a fix)
    ground_mount: GroundMount | None = None  # the ground check of the mount at the start
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rotation applied to /tf_static's mount, deg
    mount_written: bool = True  # /tf_static has a base_link -> LiDAR mount (False: the LiDAR pose is the base)
    wheel: WheelTrack | None = None  # the wheel odometry lio reads (stamps corrected: commands/slam_wheels.py)
    wheel_clock: WheelClock | None = None  # the wheel stamps' offset against the gyro, before the run
    motion_mount: MountCheck | None = None  # a first pass's motion check whose correction this run's mount carries

    @property
    def applied_rpy_deg(self) -> tuple[float, float, float]:
        """The whole rotation applied to /tf_static's mount (deg, LiDAR axes): mount_rpy_deg, then the
        correction of motion_mount (slam.mount_check.apply)."""
        return _with_motion_correction(self.mount_rpy_deg, self.motion_mount)


def _with_motion_correction(rpy: tuple[float, float, float], motion: MountCheck | None) -> tuple[float, float, float]:
    """`rpy` (deg, the correction applied to /tf_static's mount before the run), then `motion`'s."""
    if motion is None:
        return rpy
    a = _composed_rpy(rpy, motion.correction_rpy_deg)
    return float(a[0]), float(a[1]), float(a[2])


@dataclass(frozen=True, kw_only=True)
class SweepWindow:
    """Which sweeps of a log the SLAM reads (kiss-icp's --n-scans, a time window as evo's
    --t_start/--t_end): seconds after the log's first message, and at most n_scans sweeps
    (counted after lio's slam.mapping_interval_s thinning)."""

    start_s: float | None = None
    end_s: float | None = None
    n_scans: int | None = None

    def __post_init__(self) -> None:
        if self.start_s is not None and self.start_s < 0:
            raise UsageError(f"--start {self.start_s}: seconds after the log's start, >= 0")
        if self.end_s is not None and self.end_s <= (self.start_s or 0.0):
            raise UsageError(f"--end {self.end_s} must come after --start {self.start_s or 0.0}")
        if self.n_scans is not None and self.n_scans < 2:
            raise UsageError(f"--n-scans {self.n_scans}: SLAM needs at least 2 sweeps")

    @property
    def active(self) -> bool:
        return (self.start_s, self.end_s, self.n_scans) != (None, None, None)

    def describe(self) -> str:
        parts = [f"from {self.start_s:g} s" if self.start_s is not None else "",
                 f"to {self.end_s:g} s" if self.end_s is not None else "",
                 f"at most {self.n_scans} sweeps" if self.n_scans is not None else ""]
        return "sweeps " + ", ".join(p for p in parts if p) + " (after the log's start; --start/--end/--n-scans)"


def windowed(stream: Iterable[Sweep], window: SweepWindow, t0_s: float) -> Iterator[Sweep]:
    """The sweeps of `stream` inside `window` (stamps relative to t0_s, the log's start)."""
    n = 0
    for sweep in stream:
        t = sweep.stamp - t0_s
        if window.start_s is not None and t < window.start_s:
            continue
        if window.end_s is not None and t > window.end_s:
            return
        yield sweep
        n += 1
        if window.n_scans is not None and n >= window.n_scans:
            return


def run_log(log_path: Path, cfg: Config, out_dir: Path, *, method: str | None = None, progress: bool = False,
            log_id: str | None = None, window: SweepWindow | None = None) -> RunResult:
    """Replay `method` (default: the config's slam.method; given, it is written into the config)
    on one log into `out_dir`; `log_id` names the log in results (default: from its file name;
    the nightly job passes its own, unique within the night); `window`: only some sweeps."""
    from mrnc_eval.io import open_log
    from mrnc_eval.io.integrity import container_notes

    cfg = with_method(cfg, method)
    method = cfg.slam.method
    wall_start = time.perf_counter()
    result = RunResult(kind="slam", log_path=absolute_log_path(log_path), log_id=log_id or log_id_for(log_path),
                       config_hash=config_hash(cfg))
    with open_log(log_path, cfg.io) as lg:
        if not lg.has_role("lidar"):
            raise InputError(log_path, "no LiDAR topic (sensor_msgs/PointCloud2): nothing to run SLAM on")
        log.info("%s: %s, %.1f s; roles %s", log_path, lg.container, lg.duration_s,
                 ", ".join(f"{r} {t}" for r, t in sorted(lg.roles.items())))
        read = _inputs_from(_read_inputs(lg, log_path, cfg), window, lg.start_s)
        inputs = _with_wheel_clock(read, cfg)
        log.debug("inputs: IMU %s samples, GNSS %s fixes, ground truth %s poses",
                  None if inputs.imu is None else inputs.imu.stamps.size,
                  None if inputs.gnss is None else inputs.gnss.stamps.size,
                  None if inputs.ground_truth is None else len(inputs.ground_truth))
        result.extra[K.ROLES] = {r: lg.roles[r] for r in ("lidar", "imu", "gnss", "wheel_odom", "ground_truth")
                                 if r in lg.roles}
        result.extra["inputs"] = _inputs_used(lg, inputs, cfg)
        result.extra[K.GROUND_TRUTH] = ground_truth_spec(lg, log_path)  # what `table` reads back as the reference
        if window is not None and window.active:
            result.extra["window"] = {"start_s": window.start_s, "end_s": window.end_s, "n_scans": window.n_scans}
            result.warnings.append(window.describe())
        out, inputs = _replay_passes(lg, log_path, read, inputs, cfg, progress, window)
        read_notes = [*inputs.notes, *lg.health_notes()]  # samples dropped, stamps sorted, sweeps skipped
        read_notes += container_notes(Path(log_path), lg.container)  # lost or unverifiable data
    if out.stamps.size < 2:
        why = "; ".join(read_notes) or "no sweep could be registered"
        raise EvaluationError(f"{log_path}: SLAM produced {out.stamps.size} pose(s) ({why})")
    result.warnings += read_notes
    return _finish(result, out, inputs, method, cfg, out_dir, wall_start)


def run_scan_folder(folder: Path, cfg: Config, out_dir: Path, *, method: str | None = None,
                    log_id: str | None = None, window: SweepWindow | None = None) -> RunResult:
    """SLAM on a folder of .bin/.pcd scans with timestamps.txt (io/scan_folder.py), as kiss-icp
    reads one: LiDAR only, so --method kiss-icp; poses in the sensor frame (no /tf_static). A
    `ground_truth.tum` in the folder is the reference of the APE."""
    from mrnc_eval.io.scan_folder import open_scan_folder, scan_sweeps
    from mrnc_eval.io.trajectory_files import read_tum

    cfg = with_method(cfg, method)
    if cfg.slam.method != "kiss-icp":
        raise UsageError(f"{folder}: a folder of scans has no IMU for lio; run it with --method kiss-icp")
    scans = open_scan_folder(folder)
    wall_start = time.perf_counter()
    result = RunResult(kind="slam", log_path=str(folder), log_id=log_id or log_id_for(folder),
                       config_hash=config_hash(cfg))
    gt_file = folder / "ground_truth.tum"
    gt = read_tum(gt_file) if gt_file.is_file() else None
    result.extra["ground_truth"] = str(gt_file.resolve()) if gt is not None else None
    result.extra["input"] = f"scan folder: {len(scans.files)} scans ({scans.files[0].suffix}), stamps from the folder"
    if any(cfg.slam.sensor.mount_rpy_correction_deg):  # a config shared with the machine's logs: say, not fail
        result.warnings.append(f"slam.sensor.mount_rpy_correction_deg {list(cfg.slam.sensor.mount_rpy_correction_deg)} "
                               "ignored: a scan folder has no /tf_static mount (poses in the sensor frame)")
    stream: Iterator[Sweep] = scan_sweeps(scans)
    if window is not None and window.active:
        result.extra["window"] = {"start_s": window.start_s, "end_s": window.end_s, "n_scans": window.n_scans}
        result.warnings.append(window.describe())
        stream = windowed(stream, window, float(scans.stamps[0]))
    with Prefetched(stream, depth=4) as sweeps:
        out = _kiss_icp(sweeps, cfg, scans.max_gap_s)
    if out.stamps.size < 2:
        raise EvaluationError(f"{folder}: SLAM produced {out.stamps.size} pose(s)")
    inputs = LogInputs(duration_s=scans.duration_s, base_to_sensor=np.eye(4), imu=None, sensor_to_imu=np.eye(4),
                       gnss=None, ground_truth=gt, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3),
                       n_sweeps=len(scans.files), max_sweep_gap_s=scans.max_gap_s)
    return _finish(result, out, inputs, cfg.slam.method, cfg, out_dir, wall_start)


def _finish(result: RunResult, out: SlamOutput, inputs: LogInputs, method: str, cfg: Config, out_dir: Path,
            wall_start: float) -> RunResult:
    """Trajectories, metrics, APE and files of a SLAM run (a log's or a scan folder's)."""
    est = _to_base(out.stamps, out.poses, inputs.base_to_sensor, method)
    online = _to_base(out.stamps, out.online_poses if out.online_poses is not None else out.poses,
                      inputs.base_to_sensor, f"{method} online")
    keyframes = _to_base(out.kf_stamps, out.kf_poses, inputs.base_to_sensor, f"{method} keyframes")
    _add_events(result, out, inputs)
    _add_run_metrics(result, out, inputs, method, time.perf_counter() - wall_start, cfg.slam.mapping_interval_s)
    _add_trajectory_series(result, est, online, keyframes, float(out.stamps[0]))
    if inputs.ground_truth is not None:
        _add_ape(result, inputs.ground_truth, est, online, method, cfg, float(out.stamps[0]))
    else:
        where = Path(result.log_path)
        hint = ("put a ground_truth.tum (TUM) in the scan folder" if "input" in result.extra
                else ground_truth_hint(where))
        result.warnings.append(f"no ground truth: APE not computed ({hint})")
    gnss = inputs.gnss
    if gnss is not None and gnss.stamps.size > 3:
        rmse = _add_gnss_ape(result, gnss, est, inputs.antenna, method, cfg.evaluation.gnss_max_diff_s)
        _add_gnss_disagreement(result, gnss, out, rmse, clock=lambda: _gnss_clock_shift(
            gnss, est, inputs.antenna, cfg.evaluation.gnss_max_diff_s))
    _add_time_offset(result, out, cfg)
    _add_wheel_health(result, out)
    _add_wheel_clock(result, inputs, cfg)
    _add_imu_axes(result, inputs, cfg)
    if "input" not in result.extra:  # a log's /tf_static mount (a scan folder has none)
        _add_mount_check(result, est, inputs, cfg)
    _add_map_quality(result, out, cfg)
    _write_files(result, out_dir, cfg, {"trajectory.tum": est, "trajectory_online.tum": online,
                                        "keyframes.tum": keyframes}, out.map_points)
    log.info("%s: %d of %d sweeps mapped in %.2f s, %d keyframes -> %s", result.log_path, out.stamps.size, out.n_sweeps,
             out.wall_s, out.kf_stamps.size, out_dir)
    for stage, ms in out.timing_ms.items():
        log.debug("stage %s: %.2f ms per sweep over %d sweeps", stage, float(np.mean(ms)) if ms else 0.0, len(ms))
    return result


def ground_truth_hint(log_path: Path) -> str:
    """How to give a log ground truth: the sidecar file or the topic role."""
    from mrnc_eval.io.ground_truth import gt_tum_path

    return (f"give one as {gt_tum_path(log_path).name} beside the log (TUM) or --set "
            "io.roles.ground_truth=TOPIC")


def with_method(cfg: Config, method: str | None) -> Config:
    """The config with slam.method set to `method` (when given) and checked: one source of truth,
    so the effective config.yaml records the method that actually ran."""
    if method is not None:
        cfg = replace_path(cfg, "slam.method", method)
    if cfg.slam.method not in METHODS:
        raise UsageError(f"--method {cfg.slam.method!r}: choose from {', '.join(METHODS)}")
    return cfg


def _read_inputs(lg: LogReader, log_path: Path, cfg: Config) -> LogInputs:
    """IMU, GNSS, /tf_static and ground truth: the overview pass keeps them in memory."""
    duration = lg.duration_s  # the overview pass first
    lidar_frame = cfg.slam.sensor.lidar_frame
    statics = lg.static_transforms()
    frames = _static_frames(statics)
    if "base_link" in frames and lidar_frame not in frames:  # never fall back to identity silently
        raise InputError(log_path, f"slam.sensor.lidar_frame {lidar_frame!r} is not in the static transforms "
                         f"(frames: {', '.join(sorted(frames))}); set it to the clouds' frame", topic="/tf_static")
    written = _written_mount(statics, lidar_frame, log_path)
    ground = ground_check(lg, corrected_mount(written, cfg.slam.sensor.mount_rpy_correction_deg), cfg) \
        if "base_link" in frames else None
    rpy = applied_mount_rpy(cfg, ground)
    imu, imu_note = _imu_in_si(lg, log_path, cfg) if lg.has_role("imu") else (None, "")
    antenna = _antenna(statics, log_path)
    base_to_sensor, sensor_to_imu, antenna_in_sensor = _mount_frames(statics, log_path, cfg, imu, rpy, antenna)
    gnss, gnss_note = _gnss_or_none(lg, cfg)
    lidar = next(t for t in lg.topics if t.topic == lg.roles["lidar"])
    wheel, wheel_note = read_wheel_track(lg, cfg.slam)
    return LogInputs(duration_s=duration, base_to_sensor=base_to_sensor, imu=imu, sensor_to_imu=sensor_to_imu,
                     gnss=gnss, ground_truth=ground_truth_of(lg, log_path), antenna=antenna,
                     antenna_in_sensor=antenna_in_sensor, n_sweeps=lidar.count, max_sweep_gap_s=lidar.max_gap_s,
                     notes=tuple(n for n in (imu_note, gnss_note, wheel_note) if n), ground_mount=ground,
                     mount_rpy_deg=rpy, mount_written={"base_link", lidar_frame} <= frames, wheel=wheel)


def _static_frames(statics: StaticTransforms) -> set[str]:
    return {c for _, c in statics} | {p for p, _ in statics}


def _written_mount(statics: StaticTransforms, lidar_frame: str, log_path: Path) -> np.ndarray:
    """/tf_static's base_link -> LiDAR (4x4); identity when either frame is missing."""
    known = {"base_link", lidar_frame} <= _static_frames(statics)
    return static_pose(statics, "base_link", lidar_frame, where=log_path) if known else np.eye(4)


def _antenna(statics: StaticTransforms, log_path: Path) -> np.ndarray:
    """The GNSS antenna in base_link (/tf_static), m; the origin without one."""
    has = {"gnss", "base_link"} <= _static_frames(statics)
    return static_pose(statics, "base_link", "gnss", where=log_path)[:3, 3] if has else np.zeros(3)


def _mount_frames(statics: StaticTransforms, log_path: Path, cfg: Config, imu: ImuSeries | None,
                  rpy: tuple[float, float, float], antenna: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """/tf_static's base_link -> LiDAR mount turned by `rpy` (deg, LiDAR axes), the IMU's pose in that
    LiDAR frame (4x4, identity without a frame for it) and the GNSS antenna (base_link, m) in it (m)."""
    lidar_frame = cfg.slam.sensor.lidar_frame
    frames = _static_frames(statics)
    base_to_sensor = corrected_mount(_written_mount(statics, lidar_frame, log_path), rpy)
    sensor_to_imu = np.eye(4)
    if imu is not None and imu.frame_id and imu.frame_id in frames and lidar_frame in frames:
        sensor_to_imu = imu_in_corrected_sensor(static_pose(statics, lidar_frame, imu.frame_id, where=log_path),
                                                statics, lidar_frame=lidar_frame, imu_frame=imu.frame_id,
                                                rpy_deg=rpy, where=log_path)
    return base_to_sensor, sensor_to_imu, (np.linalg.inv(base_to_sensor) @ np.r_[antenna, 1.0])[:3]


def _remounted(inputs: LogInputs, lg: LogReader, log_path: Path, cfg: Config, motion: MountCheck) -> LogInputs:
    """`inputs` (as read, before the wheel clock) on the mount turned further by a first pass's motion
    check: what depends on the mount anew, the rest as read."""
    base_to_sensor, sensor_to_imu, antenna_in_sensor = _mount_frames(
        lg.static_transforms(), log_path, cfg, inputs.imu, _with_motion_correction(inputs.mount_rpy_deg, motion),
        inputs.antenna)
    return dataclasses.replace(inputs, base_to_sensor=base_to_sensor, sensor_to_imu=sensor_to_imu,
                               antenna_in_sensor=antenna_in_sensor, motion_mount=motion)


def _with_wheel_clock(inputs: LogInputs, cfg: Config) -> LogInputs:
    """The inputs with the wheel clock checked against the gyro (commands/slam_wheels.py), the gyro in
    base axes as the run reads it (slam.imu.extrinsic_rot, when set, over /tf_static)."""
    wheel, clock = clock_checked(inputs.wheel, inputs.imu, _imu_in_base(inputs, cfg), cfg.slam)
    return dataclasses.replace(inputs, wheel=wheel, wheel_clock=clock)


def _imu_in_base(inputs: LogInputs, cfg: Config) -> np.ndarray:
    """The IMU's pose in base_link as the run reads it (4x4: slam.imu.extrinsic_rot, when set, over
    /tf_static), for the checks that put its gyro into base axes."""
    from mrnc_eval.slam.imu import lidar_to_imu

    return inputs.base_to_sensor @ lidar_to_imu(cfg.slam.imu, inputs.sensor_to_imu)


def _imu_in_si(lg: LogReader, log_path: Path, cfg: Config) -> tuple[ImuSeries, str]:
    """The IMU with its accelerometer in m/s^2 (commands/info_sensors.py `imu_in_si`, `info`'s rule too):
    a driver writing g is scaled and noted; a specific force in neither unit is an input error for lio,
    which integrates it, and a note for kiss-icp, which does not read the IMU."""
    from mrnc_eval.commands.info_sensors import imu_in_si

    topic = lg.roles["imu"]
    imu, found = imu_in_si(lg.imu(), topic, cfg)
    if not found:
        return imu, ""
    level, _, message = found[0]
    if level == "error" and cfg.slam.method == "lio":
        raise InputError(log_path, message, topic=topic)
    return imu, f"IMU {topic}: {message}" + (" (kiss-icp does not read it)" if level == "error" else "")


def ground_check(lg: LogReader, base_to_sensor: np.ndarray, cfg: Config) -> GroundMount | None:
    """The mount's roll and pitch from the ground in the log's first sweeps (slam/ground_mount.py), read
    through `base_to_sensor` (/tf_static's mount with the user's correction); None when switched off."""
    from mrnc_eval.slam.ground_mount import ground_mount

    gcfg = cfg.slam.ground_mount
    if not gcfg.enabled:
        return None
    t0 = time.process_time()
    box = cfg.slam.features.body_crop_box_m
    clouds: list[np.ndarray] = []
    first = None
    sweeps = lg.sweeps(note_skips=False)  # the run's own pass notes the sweeps it skips
    try:
        for sweep in sweeps:
            first = sweep.stamp if first is None else first  # the span from the first sweep, empty or not
            if len(clouds) >= gcfg.max_sweeps or sweep.stamp - first > gcfg.span_s:
                break
            if not len(sweep):  # no returns (a driver starting up): nothing to read, not a sweep of the ground
                continue
            stride = -(-len(sweep.points) // gcfg.max_points_per_sweep)  # ceil: a dense sweep thinned first
            p = sweep.points[::stride].astype(np.float64)
            p = p[np.all(np.isfinite(p), axis=1)]
            if box is not None:  # the machine's own body, in the cloud frame
                p = p[~np.all((p >= np.asarray(box[:3])) & (p <= np.asarray(box[3:])), axis=1)]
            clouds.append(p @ base_to_sensor[:3, :3].T + base_to_sensor[:3, 3])
            if len(clouds) >= gcfg.max_sweeps:  # enough: the next sweep is not decoded only to stop
                break
    finally:
        if isinstance(sweeps, Generator):  # stop the decoder of the stream started here
            sweeps.close()
    points = np.vstack(clouds) if clouds else np.zeros((0, 3))
    labels = np.repeat(np.arange(len(clouds)), [c.shape[0] for c in clouds])
    out = ground_mount(points, base_to_sensor[:3, :3], gcfg, sweep=labels)
    out.cpu_ms = (time.process_time() - t0) * 1e3
    out.sweeps = len(clouds)
    return out


def applied_mount_rpy(cfg: Config, ground: GroundMount | None) -> tuple[float, float, float]:
    """The rotation right-multiplied onto /tf_static's LiDAR mount (deg, LiDAR axes): the user's
    slam.sensor.mount_rpy_correction_deg when set, else the ground check's flagged reading when
    slam.ground_mount.apply, else none."""
    user = cfg.slam.sensor.mount_rpy_correction_deg
    if any(user) or ground is None or not cfg.slam.ground_mount.apply or ground.verdict != "misaligned":
        return user
    return ground.correction_rpy_deg


def _gnss_or_none(lg: LogReader, cfg: Config) -> tuple[GnssSeries | None, str]:
    """GNSS when usable, else why not. A log without any fix is a legitimate recording (GNSS
    skipped, noted); invalid fixes are an error unless GNSS is off (--no-gps), where they are noted."""
    if not lg.has_role("gnss"):
        return None, ""
    try:
        return lg.gnss(), ""
    except NoGnssFix as err:
        return None, f"GNSS not used: {err.problem}"
    except InputError as err:
        if cfg.slam.gps.enabled:
            raise
        return None, f"GNSS not used: {err.problem}"


def _replay(lg: LogReader, inputs: LogInputs, cfg: Config, progress: bool, window: SweepWindow | None = None
            ) -> SlamOutput:
    """Run the configured method over the sweep stream; both methods decode ahead in a reader thread
    ("read" = the time still waited), lio also prepares each sweep there (slam/sweep_prep.py), unless
    slam.threads is 1: then everything runs in turn on this thread."""
    from mrnc_eval import gc_pause
    from mrnc_eval.slam.replay import run_slam
    from mrnc_eval.slam.warmup import warm_up

    lio = cfg.slam.method == "lio"
    with progress_bar(inputs.n_sweeps, progress) as b:
        task = b.add_task("SLAM sweeps", total=inputs.n_sweeps) if b else None
        tick = (lambda n: b.update(task, completed=n)) if b and task is not None else None
        stream = lg.sweeps(keep=MappingInterval(interval_s=cfg.slam.mapping_interval_s).take) if lio else lg.sweeps()
        if window is not None and window.active:
            stream = windowed(stream, window, lg.start_s)
        if not lio:
            with Prefetched(stream, depth=4) as sweeps:
                return _kiss_icp(sweeps, cfg, inputs.max_sweep_gap_s)
        threads = run_threads(cfg.slam.threads)
        warmup_ms = warm_up(cfg.slam)  # first-use costs, before the reader starts and the clock runs
        # the reader takes one core and prepares what needs no pose there; pykdtree's OpenMP team (loop
        # closure, map quality: matching searches its own tree, slam/_match_kernels.c, on this thread)
        # the rest (two cores: one each, no team to wake per query batch while the reader holds the
        # other core). One thread: the raw sweeps, prepared in line by run_slam after its read timer.
        # Two prepared sweeps queued: an OS0-128 x 1024 one is ~8 MB, and forest30 mapped every sweep
        # peaks ~15 MB lower than with four (median 208 against 222 MB) in the same wall time (5.4 s)
        items = _run_items(stream, cfg.slam, prepare=threads > 1)
        import gtsam  # noqa: F401 - run_slam's first use of it, here while collection is still paused (~3 ms less)

        gc_pause.resume()  # the start-up's objects are made (cli.slam paused collection for them)
        with openmp_threads(max(1, threads - 1)), \
                (Prefetched(items, depth=2) if threads > 1 else closing(items)) as sweeps:
            return run_slam(sweeps, inputs.imu, cfg.slam, sensor_to_imu=inputs.sensor_to_imu, gnss=inputs.gnss,
                            antenna_in_sensor=inputs.antenna_in_sensor, wheel=inputs.wheel,
                            base_to_sensor=inputs.base_to_sensor, progress=tick, warmup_ms=warmup_ms,
                            workers=threads)


def _run_items(stream: Iterator[Sweep], cfg: SlamConfig, *, prepare: bool
               ) -> Generator[Sweep | PreparedSweep, None, None]:
    """The sweeps, with what needs no pose prepared where the stream is read when `prepare`; the
    log's stream is closed in the reading thread whatever happens (a generator expression would
    leave that to the garbage collector, after the log is closed)."""
    from mrnc_eval.slam.sweep_prep import prepare_sweep

    try:
        for sweep in stream:
            yield prepare_sweep(sweep, cfg) if prepare else sweep
    finally:
        close = getattr(stream, "close", None)
        if close is not None:
            close()


def _replay_passes(lg: LogReader, log_path: Path, read: LogInputs, inputs: LogInputs, cfg: Config,
                   progress: bool, window: SweepWindow | None) -> tuple[SlamOutput, LogInputs]:
    """The replay, and again with everything found so far applied while a pass finds something to
    correct: the IMU-LiDAR offset left standing out (up to slam.imu.time_offset_passes runs; one pass
    reads only part of a lag, its deskew and keyframes ran on the lagged IMU) and, once, the LiDAR mount
    the first pass's motion flags (slam.mount_check.apply). One second run corrects both. The output is
    the last pass's, with the offset as all passes found it (after the configured
    slam.imu.time_offset_s), and the inputs it ran on. `read`: the inputs as read (before the wheel
    clock), `inputs`: as the first pass runs on them."""
    out = _replay(lg, inputs, cfg, progress, window)
    motion = _mount_to_apply(out, inputs, cfg)
    applied, runs, mount_note = 0.0, 1, None
    while True:
        left = out.imu_time_offset_s  # this pass's own estimate, against the IMU as it ran
        more = (runs < cfg.slam.imu.time_offset_passes and cfg.slam.method == "lio" and left is not None
                and _offset_stands_out(left, out.imu_time_offset_sigma_s))
        if not more and motion is None:
            break
        runs += 1
        if more and left is not None:
            applied += left
            log.info("IMU-LiDAR offset %.1f ms left: pass %d with %.1f ms applied", left * 1e3, runs, applied * 1e3)
        if motion is not None:
            inputs = _with_wheel_clock(_remounted(read, lg, log_path, cfg, motion), cfg)
            value = _rpy_text(inputs.applied_rpy_deg)
            log.info("%s: LiDAR mount off by %s: pass with /tf_static's mount turned by %s deg", log_path,
                     "; ".join(motion.reasons), value)
            mount_note = (f"pass of the log with the LiDAR mount turned by {value} deg (slam.mount_check.apply: "
                          f"the first pass's motion read {'; '.join(motion.reasons)})")
            motion = None
        shifted = replace_path(cfg, "slam.imu.time_offset_s", cfg.slam.imu.time_offset_s + applied)
        out = _replay(lg, inputs, shifted, progress, window)
    return _with_pass_notes(out, runs, applied, mount_note, inputs), inputs


def _with_pass_notes(out: SlamOutput, runs: int, applied: float, mount_note: str | None,
                     inputs: LogInputs) -> SlamOutput:
    """The last pass's output with the offset all passes found (a pass without an estimate keeps what was
    applied) and events that say what it ran with."""
    t = float(out.stamps[0]) if out.stamps.size else 0.0
    notes = []
    if mount_note is not None:
        notes.append(SlamEvent(t=t, kind="mount", message=mount_note,
                               data={"applied_rpy_deg": list(inputs.applied_rpy_deg)}))
    if applied != 0.0:
        notes.append(SlamEvent(t=t, kind="imu_time_offset", message=f"pass {runs} of the log with the IMU stamps "
                               f"{applied * 1e3:+.1f} ms earlier (slam.imu.time_offset_passes)",
                               data={"pass": runs, "applied_s": applied}))
    left = out.imu_time_offset_s
    found = left if applied == 0.0 else applied + (0.0 if left is None else left)
    return dataclasses.replace(out, imu_time_offset_s=found, events=[*notes, *out.events]) if notes else out


def _mount_to_apply(out: SlamOutput, inputs: LogInputs, cfg: Config) -> MountCheck | None:
    """The motion check of a lio pass's trajectory when it flags the mount and slam.mount_check.apply
    may act on it: no user correction set (the user's word stands), the flagged angles known to
    apply_max_sigma_deg and a correction within the range slam.sensor.mount_rpy_correction_deg takes;
    else None."""
    from mrnc_eval.geometry import lie
    from mrnc_eval.slam.mount_check import mount_check

    mcfg = cfg.slam.mount_check
    if (cfg.slam.method != "lio" or not (mcfg.enabled and mcfg.apply) or not inputs.mount_written
            or any(cfg.slam.sensor.mount_rpy_correction_deg) or out.stamps.size < 2):
        return None
    est = _to_base(out.stamps, out.poses, inputs.base_to_sensor, "first pass")
    check = mount_check(est.stamps, lie.poses(est), inputs.base_to_sensor[:3, :3], mcfg)
    total = _with_motion_correction(inputs.mount_rpy_deg, check)
    if (check.verdict != "misaligned" or check.flagged_sigma_deg() > mcfg.apply_max_sigma_deg
            or np.any(np.abs(total) > _correction_limit(cfg))):
        return None
    return check


def _offset_stands_out(offset: float, sigma: float | None) -> bool:
    """The health finding's rule: more than IMU_OFFSET_FINDING_S and more than 2 standard errors."""
    return abs(offset) > IMU_OFFSET_FINDING_S and (sigma is None or abs(offset) > 2 * sigma)


def _inputs_used(lg: LogReader, inputs: LogInputs, cfg: Config) -> dict[str, str]:
    """role -> topic of every topic the run reads as an input (never the ground truth: io/roles.py
    rule 4)."""
    lio = cfg.slam.method == "lio"
    used = {"lidar": True, "imu": lio and inputs.imu is not None,
            "gnss": lio and inputs.gnss is not None and cfg.slam.gps.enabled,
            "wheel_odom": lio and cfg.slam.wheel_odom.enabled and lg.has_role("wheel_odom")}
    return {role: lg.roles[role] for role, yes in used.items() if yes and role in lg.roles}


def _from_start(stamps: np.ndarray, window: SweepWindow | None, t0_s: float) -> np.ndarray:
    """Mask of the samples at or after `window`'s start (seconds after t0_s, the log's start)."""
    if window is None or window.start_s is None:
        return np.ones(stamps.shape, dtype=bool)
    return np.asarray(stamps >= t0_s + window.start_s)


def _inputs_from(inputs: LogInputs, window: SweepWindow | None, t0_s: float) -> LogInputs:
    """The IMU, GNSS and wheels from `window`'s start on, as if the log began there (--start: a log
    recorded mid-drive; the IMU set-up and the wheel calibration must not see the standing start before
    it). The end (--end, --n-scans) cuts only the sweeps: what follows the last one is never used."""
    if window is None or window.start_s is None:
        return inputs
    imu, gnss, wheel = inputs.imu, inputs.gnss, inputs.wheel
    if imu is not None:
        k = _from_start(imu.stamps, window, t0_s)
        imu = dataclasses.replace(imu, stamps=imu.stamps[k], acc=imu.acc[k], gyro=imu.gyro[k], orientation_xyzw=(
            None if imu.orientation_xyzw is None else imu.orientation_xyzw[k]))
    if gnss is not None:
        k = _from_start(gnss.stamps, window, t0_s)
        gnss = dataclasses.replace(gnss, stamps=gnss.stamps[k], lla=gnss.lla[k], enu=gnss.enu[k],
                                   covariance=gnss.covariance[k]) if k.any() else None
    if wheel is not None:
        k = _from_start(wheel.stamps, window, t0_s)
        wheel = WheelTrack(stamps=wheel.stamps[k], positions=wheel.positions[k], quat_xyzw=wheel.quat_xyzw[k])
    return dataclasses.replace(inputs, imu=imu, gnss=gnss, wheel=wheel)


def _kiss_icp_deskew(first: Sweep | None, max_gap_s: float) -> tuple[bool, str | None]:
    """kiss-icp deskews a sweep with the motion since the previous one spread over one sweep
    period: right only when sweeps follow each other. Off (and said) when the log has no
    per-point time or two consecutive sweeps are more than 1.5 sweep periods apart (a throttled
    recording: the motion of several periods would be squeezed into one)."""
    if first is None or first.point_time is None or first.point_time.size == 0:
        return False, "kiss-icp ran without deskew: the sweeps have no per-point time"
    period = float(first.point_time.max() - first.point_time.min())
    if max_gap_s > THROTTLED_GAP_PERIODS * period:
        return False, (f"kiss-icp ran with deskew off: consecutive sweeps up to {max_gap_s:.3f} s apart, more than "
                       f"{THROTTLED_GAP_PERIODS:g} sweep periods ({period:.3f} s) - a throttled recording, where its "
                       "deskew would spread several periods of motion over one sweep")
    return True, None


def _kiss_icp(sweeps: Iterable[Sweep], cfg: Config, max_gap_s: float) -> SlamOutput:
    """The peer on the same Sweep arrays, configured as kiss-icp's own runner configures it (its
    default config: max range 100 m, voxel 1 m, min range 0, adaptive threshold). Deviations, each
    required by the input: no-return pixels are already dropped by the reader (kiss-icp's loader
    keeps the zeros and its deskew moves them off the origin into phantom points near the sensor),
    the body crop box (the machine's own body is in the cloud), and deskew off on throttled logs or
    clouds without per-point time (`_kiss_icp_deskew`). tests/slam/test_kiss_icp_peer.py checks
    that the poses equal those of kiss-icp's own OdometryPipeline."""
    try:
        from kiss_icp.config import load_config
        from kiss_icp.kiss_icp import KissICP
    except ImportError as err:
        raise UsageError("--method kiss-icp needs the kiss-icp extra: pip install 'mrnc-eval[kiss-icp]'") from err
    from mrnc_eval.slam.range_image import outside_box

    stream: Iterator[Sweep] = iter(sweeps)
    first = next(stream, None)
    deskew, why = _kiss_icp_deskew(first, max_gap_s)
    kcfg = load_config(None)
    kcfg.data.deskew = deskew
    icp = KissICP(kcfg)
    if first is not None:
        stream = itertools.chain([first], stream)
    stamps, poses = [], []
    t_match, t_read = [], []
    wall0 = t_prev = time.perf_counter()
    n = 0
    for s in stream:
        n += 1
        t0 = time.perf_counter()
        t_read.append((t0 - t_prev) * 1e3)
        # kiss-icp normalises per-point time to [0, 1] itself (min to max of the sweep); with
        # deskew off it does not read the stamps
        ts = s.point_time.astype(np.float64) if deskew and s.point_time is not None else np.zeros(len(s))
        keep = outside_box(s.points, cfg.slam.features.body_crop_box_m)  # the same body crop as lio
        icp.register_frame(s.points[keep].astype(np.float64), ts[keep])
        t_match.append((time.perf_counter() - t0) * 1e3)
        stamps.append(s.stamp)
        poses.append(np.asarray(icp.last_pose))
        t_prev = time.perf_counter()
    timing = {st: [0.0] * len(t_match) for st in STAGES}
    timing["matching"], timing["read"] = t_match, t_read
    warnings = [why] if why else []
    return SlamOutput(stamps=np.asarray(stamps), poses=np.asarray(poses), kf_stamps=np.asarray(stamps),
                      kf_poses=np.asarray(poses), map_points=np.zeros((0, 3)), timing_ms=timing, events=[],
                      warnings=warnings, n_sweeps=n, wall_s=time.perf_counter() - wall0, deskew=deskew)


def _to_base(stamps: np.ndarray, sensor_poses: np.ndarray, base_to_sensor: np.ndarray, name: str) -> Trajectory:
    """LiDAR poses in the map as base_link poses (through /tf_static)."""
    base = sensor_poses.reshape(-1, 4, 4) @ np.linalg.inv(base_to_sensor)
    return Trajectory(stamps, base[:, :3, 3], rotation.matrix_to_quat(base[:, :3, :3]), name=name,
                      frame_id="map", child_frame_id="base_link")


def _add_events(result: RunResult, out: SlamOutput, inputs: LogInputs) -> None:
    result.warnings += out.warnings
    if inputs.imu is None:
        result.warnings.append("log has no IMU topic")
    _add_dropped_inputs(result, out, inputs)
    t_start = float(out.stamps[0])
    for e in out.events:
        result.events.append(Event(t_s=e.t - t_start, kind=e.kind, message=e.message, data=e.data))


def _add_dropped_inputs(result: RunResult, out: SlamOutput, inputs: LogInputs) -> None:
    """Every input the replay could not use, counted (metric) and said (warning): sweeps with no
    valid point, and mapped sweeps with no IMU sample since the previous one (a slow or gappy
    IMU: those sweeps ran without preintegration or deskew rotation)."""
    if out.empty_sweeps:
        result.metrics.append(Metric(name="sweeps_empty", value=out.empty_sweeps, unit="", group="slam",
                                     note="sweeps with no valid point (empty, all zero or non-finite), not mapped"))
        result.warnings.append(f"{out.empty_sweeps} of {out.n_sweeps} sweep(s) had no valid point (empty, all zero "
                               "or non-finite): dropped")
    if inputs.imu is None or out.stamps.size < 2:
        return
    imu_t = np.sort(inputs.imu.stamps)
    sweeps_t = np.asarray(out.stamps, dtype=float)
    counts = np.searchsorted(imu_t, sweeps_t[1:], side="right") - np.searchsorted(imu_t, sweeps_t[:-1], side="right")
    without = int(np.count_nonzero(counts == 0))
    result.metrics.append(Metric(name="sweeps_without_imu", value=without, unit="", group="slam", lower_is_better=True,
                                 note="mapped sweeps with no IMU sample since the previous mapped sweep"))
    if without:
        span = float(imu_t[-1] - imu_t[0]) if imu_t.size > 1 else 0.0
        rate = (imu_t.size - 1) / span if span > 0 else 0.0
        result.warnings.append(f"{without} of {sweeps_t.size - 1} mapped sweeps had no IMU sample since the previous "
                               f"one (IMU at {rate:.1f} Hz): they ran without IMU preintegration")


def _add_run_metrics(result: RunResult, out: SlamOutput, inputs: LogInputs, method: str, total_s: float,
                     mapping_interval_s: float) -> None:
    """Real-time factors, counts, per-stage timing and run details."""
    duration = inputs.duration_s
    rtf = duration / out.wall_s if out.wall_s > 0 else float("inf")
    result.metrics += [Metric(name="rtf", value=rtf, unit="", group="slam", lower_is_better=False,
                              note="log duration / wall time of the SLAM over the sweep stream (decoding included)"),
                       Metric(name="rtf_end_to_end", value=duration / total_s, unit="", group="slam",
                              lower_is_better=False,
                              note="log duration / wall time including reading IMU, GNSS and ground truth"),
                       Metric(name="sweeps_processed", value=int(out.stamps.size), unit="", group="slam"),
                       Metric(name="keyframes", value=int(out.kf_stamps.size), unit="", group="slam"),
                       Metric(name="loop_closures", value=sum(e.kind == "loop_closure" for e in out.events), unit="",
                              group="slam"),
                       Metric(name="degeneracy_events", value=sum(e.kind == "degeneracy" for e in out.events),
                              unit="", group="slam")]
    rate_hz = out.stamps.size / duration if duration > 0 else float("nan")
    result.metrics.append(Metric(name="mapping_rate_hz", value=rate_hz, unit="Hz", group="slam",
                                 note="sweeps mapped per second of log: the work the RTF was measured at"))
    timing = _stage_timing(out)
    for stage in STAGES:
        result.metrics.append(Metric(name=f"ms_per_sweep_{stage}", value=timing[stage]["mean"], unit="ms",
                                     group="slam/timing"))
    # of the sweeps in the log (not of those the interval let through): "134 of 236", and why
    every = (f"every {mapping_interval_s:g} s or more (slam.mapping_interval_s)" if method == "lio"
             else "every sweep")
    result.extra[K.MAPPING_RATE] = (f"mapping {out.stamps.size} of {max(inputs.n_sweeps, out.n_sweeps)} sweeps, "
                                    f"{every}, {rate_hz:.1f} Hz")
    result.extra[K.DESKEW] = out.deskew
    result.extra.update({K.METHOD: method, K.TIMING_MS: timing, K.WALL_S: out.wall_s, K.LOG_DURATION_S: duration,
                         "sweeps_decoded": out.n_sweeps, "wall_total_s": total_s,
                         K.FIRST_SWEEP_MS: float(sum(v[0] for v in out.timing_ms.values() if v)),
                         "warmup_ms": dict(out.warmup_ms), K.WARMUP_TOTAL_MS: float(sum(out.warmup_ms.values())),
                         "imu_bias": None if out.imu_bias is None else out.imu_bias.tolist(),
                         "imu_noise": out.imu_noise,  # the IMU's noise and biases from stationary stretches
                         "frames": {"trajectory.tum": "map -> base_link (LiDAR poses through /tf_static), "
                                                      "smoothed: each sweep re-anchored to its final keyframe",
                                    "trajectory_online.tum": "the same frames, each sweep's pose as estimated "
                                                             "when it was processed",
                                    "stamps": "sweep header stamps (sweep start)"}})
    if method == "lio" and inputs.imu is not None and inputs.imu.orientation_xyzw is None:
        result.extra["notes"] = ["6-axis IMU (no orientation): the 9-axis roll/pitch blend "
                                 "(slam.imu.rpy_weight) does not apply"]


def _stage_timing(out: SlamOutput) -> dict[str, dict[str, float]]:
    """Mean, p95 and max ms per stage. One-off costs are not in them: the warm-up before the loop
    pays first-use costs (slam/warmup.py, reported as warmup_ms) and the first sweep, which
    also starts the graphs, is left out (reported as first_sweep_ms)."""
    timing = {}
    for stage in STAGES:
        vals = np.asarray(out.timing_ms[stage][1:] or out.timing_ms[stage] or [0.0])
        timing[stage] = {"mean": float(vals.mean()), "p95": float(np.percentile(vals, 95)), "max": float(vals.max())}
    return timing


def _add_trajectory_series(result: RunResult, est: Trajectory, online: Trajectory, keyframes: Trajectory,
                           t_start: float) -> None:
    result.series[K.EST_T] = est.stamps - t_start
    result.series[K.EST_XYZ] = est.positions
    result.series[K.EST_ONLINE_XYZ] = online.positions
    result.series[K.KF_XYZ] = keyframes.positions


def _end_drift(gt: Trajectory, est: Trajectory, max_diff_s: float) -> float:
    """Distance (m) between the estimated and true last position once the first poses coincide."""
    from mrnc_eval.evaluation.ape import ape

    return float(ape(gt, est, align="origin", max_diff=max_diff_s).errors[-1])


def _add_ape(result: RunResult, gt: Trajectory, est: Trajectory, online: Trajectory, method: str, cfg: Config,
             t_start: float) -> None:
    """APE (SE(3) aligned) and end drift against ground truth of the smoothed trajectory (each
    sweep re-anchored to its final, loop-corrected keyframe) and of the online one (each sweep's
    pose when it was processed); the one-cell Table I of the one slam.table_trajectory names."""
    smoothed = _ape_smoothed(result, gt, est, cfg, t_start)
    on = _ape_online(result, gt, online, cfg, t_start)
    cell = on if cfg.slam.table_trajectory == "online" else smoothed
    result.tables.append(table_one({(result.log_id, method): cell}, [result.log_id], [method],
                                   title=f"APE RMSE (SE(3) aligned, {cfg.slam.table_trajectory} trajectory)"))


def _ape_online(result: RunResult, gt: Trajectory, online: Trajectory, cfg: Config, t_start: float) -> Cell:
    from mrnc_eval.evaluation.ape import ape

    try:
        r = ape(gt, online, align="se3", max_diff=cfg.evaluation.gt_max_diff_s)
    except EvaluationError as err:
        result.warnings.append(f"APE of the online trajectory failed: {err}")
        return Cell(None, str(err))
    result.metrics += [Metric(name="ape_online_rmse_m", value=r.stats["rmse"], unit="m", group="slam/ape",
                              note="online trajectory: each sweep's pose as estimated when it was processed"),
                       Metric(name="end_drift_online_m", value=_end_drift(gt, online, cfg.evaluation.gt_max_diff_s),
                              unit="m", group="slam/ape",
                              note="end drift of the online trajectory")]
    result.series[K.ape_err(K.ONLINE)] = r.errors
    result.series[K.EST_ONLINE_ALIGNED_XYZ] = r.est_poses[:, :3, 3]
    result.series[K.ape_t(K.ONLINE)] = r.stamps - t_start
    return judge(r.stats["rmse"], r.n, r.span_s, r.ref_span_s, min_matches=cfg.evaluation.failed_min_matches,
                 min_span_fraction=cfg.evaluation.failed_min_span_fraction)


def _ape_smoothed(result: RunResult, gt: Trajectory, est: Trajectory, cfg: Config, t_start: float) -> Cell:
    from mrnc_eval.evaluation.ape import ape

    try:
        r = ape(gt, est, align="se3", max_diff=cfg.evaluation.gt_max_diff_s)
        result.metrics += [Metric(name="ape_rmse_m", value=r.stats["rmse"], unit="m", group="slam/ape"),
                           Metric(name="ape_mean_m", value=r.stats["mean"], unit="m", group="slam/ape"),
                           Metric(name="ape_max_m", value=r.stats["max"], unit="m", group="slam/ape"),
                           Metric(name="ape_n", value=r.n, unit="", group="slam/ape"),
                           Metric(name="ape_span_s", value=r.span_s, unit="s", group="slam/ape"),
                           Metric(name="end_drift_m", value=_end_drift(gt, est, cfg.evaluation.gt_max_diff_s),
                                  unit="m", group="slam/ape",
                                  note="position error of the last pose with the first pose aligned to the "
                                       "ground truth: the drift accumulated over the log")]
        result.series[K.ape_t(K.SMOOTHED)] = r.stamps - t_start
        result.series[K.ape_err(K.SMOOTHED)] = r.errors
        result.series[K.REF_XYZ] = r.ref_poses[:, :3, 3]
        result.series[K.EST_ALIGNED_XYZ] = r.est_poses[:, :3, 3]
        return judge(r.stats["rmse"], r.n, r.span_s, r.ref_span_s, min_matches=cfg.evaluation.failed_min_matches,
                     min_span_fraction=cfg.evaluation.failed_min_span_fraction)
    except EvaluationError as err:
        result.warnings.append(f"APE against ground truth failed: {err}")
        return Cell(None, str(err))


GNSS_CLOCK_SHIFTS_S = np.arange(-30.0, 30.0 + 1e-9, 0.25)  # GNSS stamp offsets tried when the fixes disagree


def _ape_against_fixes(gnss: GnssSeries, est: Trajectory, antenna: np.ndarray, max_diff_s: float, *,
                       shift_s: float = 0.0) -> ApeResult:
    """2-D APE (yaw + translation aligned) of the trajectory's antenna against the GNSS fixes in ENU,
    the fixes' stamps less shift_s; raises EvaluationError when it cannot be computed."""
    from mrnc_eval.evaluation.ape import ape

    ref = Trajectory(gnss.stamps - shift_s, gnss.enu, np.tile([0, 0, 0, 1.0], (gnss.stamps.size, 1)), name="gnss")
    antenna_track = Trajectory(est.stamps, est.positions + rotation.quat_to_matrix(est.quat_xyzw) @ antenna,
                               est.quat_xyzw, name=est.name)
    return ape(ref, antenna_track, align="yaw", relation="point", max_diff=max_diff_s, plane="xy")


def _gnss_clock_shift(gnss: GnssSeries, est: Trajectory, antenna: np.ndarray, max_diff_s: float
                      ) -> tuple[float, float] | None:
    """The shift of the GNSS stamps (s, within +-30 s) that brings the fixes closest to the
    trajectory's antenna (2-D, yaw + translation aligned) with at least half the fixes still
    matched, and the RMS then (m); None when no shift could be scored."""

    def rmse(shift: float) -> float:
        try:
            r = _ape_against_fixes(gnss, est, antenna, max_diff_s, shift_s=shift)
        except EvaluationError:
            return np.inf
        return float(r.stats["rmse"]) if r.errors.size >= 0.5 * gnss.stamps.size else np.inf

    coarse = min(GNSS_CLOCK_SHIFTS_S, key=rmse)  # then 0.05 s steps around it
    best = min(np.arange(coarse - 0.25, coarse + 0.25 + 1e-9, 0.05), key=rmse)
    score = rmse(best)
    return (float(best), score) if np.isfinite(score) else None


def _add_gnss_ape(result: RunResult, gnss: GnssSeries, est: Trajectory, antenna: np.ndarray, method: str,
                  max_diff_s: float) -> float | None:
    """2-D APE of the antenna track against the GNSS fixes (yaw + translation aligned); its RMSE (m),
    None when it could not be computed."""
    try:
        rg = _ape_against_fixes(gnss, dataclasses.replace(est, name=method), antenna, max_diff_s)
        result.metrics.append(Metric(name="ape_gnss_rmse_m", value=rg.stats["rmse"], unit="m", group="slam/ape",
                                     note="2-D, yaw + translation alignment, against GNSS in ENU"))
        return float(rg.stats["rmse"])
    except EvaluationError as err:
        result.warnings.append(f"APE against GNSS failed: {err}")
        return None


def _add_gnss_disagreement(result: RunResult, gnss: GnssSeries, out: SlamOutput, rmse: float | None, *,
                           clock: Callable[[], tuple[float, float] | None] | None = None) -> None:
    """A health finding when the trajectory is far from the fixes, beyond what the fixes' own sigma
    explains, naming the likely cause: GNSS stamps off the LiDAR's clock (`clock`: the shift that
    brings the fixes onto the trajectory, and the RMS then, m; asked only here), a LiDAR that saw too
    little structure with nothing else to hold x, y and yaw (the IMU dead-reckons), or else the GNSS
    (antenna lever arm, fix quality). `rmse`: the trajectory's 2-D APE against the fixes
    (_add_gnss_ape), m."""
    sigma = float(np.median(np.sqrt(np.max(np.diagonal(gnss.covariance, axis1=1, axis2=2)[:, :2], axis=1))))
    limit = max(GNSS_DISAGREE_MIN_M, GNSS_DISAGREE_SIGMAS * sigma)
    if rmse is None or not np.isfinite(rmse) or rmse <= limit:
        return
    degenerate = 0.0 if out.degenerate is None or out.degenerate.size == 0 else float(np.mean(out.degenerate))
    wheels = "wheel_odom" in result.extra.get("inputs", {})
    track = next((e.t for e in out.events if e.data.get("gnss_track") == "engaged"), None)
    shift = clock() if clock is not None else None
    if shift is not None and shift[1] <= min(limit, 0.5 * rmse):  # the fixes fit once their stamps move
        why = (f"the GNSS stamps look {shift[0]:+.2f} s off the LiDAR's (moved by that, the trajectory is "
               f"{shift[1]:.2f} m RMS from the fixes)" + (": 18 s is GPS time against UTC (leap seconds)"
                                                          if abs(abs(shift[0]) - 18.0) < 0.5 else "")
               + " - check the receiver's time source and how the driver stamps the fixes")
    elif degenerate > 0.5 and track is not None:  # x, y followed the fixes: their alignment or the fixes
        why = (f"the LiDAR saw too little structure (scan-to-map degenerate on {degenerate:.0%} of the sweeps) "
               f"and x, y followed the GNSS track from {track - out.stamps[0]:.1f} s: check the fixes (multipath, "
               "the antenna's base_link -> gnss transform) and the first seconds' dead reckoning")
    elif degenerate > 0.5:
        why = (f"the LiDAR saw too little structure (scan-to-map degenerate on {degenerate:.0%} of the sweeps)"
               + ("" if wheels else " and no wheel odometry was used, so x, y and yaw are IMU dead reckoning")
               + ": the trajectory, not the GNSS, is the likely culprit")
    else:
        why = "check the GNSS (the antenna's base_link -> gnss transform in /tf_static, fix quality) and the LiDAR"
    text = (f"the trajectory is {rmse:.1f} m RMS from the GNSS fixes (yaw + translation aligned), whose own "
            f"sigma is {sigma:.2f} m: {why}")
    result.warnings.append(text)
    data = {"ape_gnss_rmse_m": rmse, "gnss_sigma_m": sigma, "degenerate_fraction": degenerate}
    result.events.append(Event(t_s=0.0, kind="health", message=text, data=data))


def _add_time_offset(result: RunResult, out: SlamOutput, cfg: Config) -> None:
    """The IMU-LiDAR offset left after slam.imu.time_offset_s; a health finding above 2 ms."""
    if out.imu_time_offset_s is None:
        return
    offset = out.imu_time_offset_s
    result.metrics.append(Metric(name="imu_time_offset_s", value=offset, unit="s", group="slam/health",
                                 note="IMU clock lag behind the LiDAR's, estimated by correlating the LiDAR's "
                                      "rotation rate with the gyro (positive: IMU stamps late; slam.imu."
                                      "time_offset_from: the sweeps re-matched after the run, or the online poses), "
                                      "after applying slam.imu.time_offset_s"))
    sigma = out.imu_time_offset_sigma_s
    if sigma is not None and np.isfinite(sigma):
        result.metrics.append(Metric(name="imu_time_offset_sigma_s", value=sigma, unit="s", group="slam/health",
                                     note="standard error of imu_time_offset_s (re-match: delete-one-block "
                                          "jackknife over 10 stretches of the log, ~1 ms on a 40 s log; online: "
                                          "formal, rate residuals taken as independent, a lower bound)"))
    if out.imu_time_offset_cpu_ms > 0:
        result.metrics.append(Metric(name="imu_time_offset_cpu_ms", value=out.imu_time_offset_cpu_ms, unit="ms",
                                     group="slam/timing", note="CPU time of the offset's re-match after the run"))
    if _offset_stands_out(offset, sigma):
        spread = f" +- {sigma * 1e3:.1f}" if sigma is not None and np.isfinite(sigma) else ""
        text = (f"IMU-LiDAR time offset {offset * 1e3:.1f}{spread} ms (> {IMU_OFFSET_FINDING_S * 1e3:.0f} ms): the IMU "
                f"stamps look {'late' if offset > 0 else 'early'}; set slam.imu.time_offset_s="
                f"{cfg.slam.imu.time_offset_s + offset:.4f}")
        result.warnings.append(text)
        data = {"imu_time_offset_s": offset} | ({"imu_time_offset_sigma_s": sigma} if spread else {})
        result.events.append(Event(t_s=0.0, kind="health", message=text, data=data))


def _add_wheel_health(result: RunResult, out: SlamOutput) -> None:
    """The online wheel calibration (slam/wheel_health.py): metrics, the whole record in metrics.json
    (`wheel_health`) and the result, and a warning when the wheels disagree with the gyro or LiDAR."""
    h = out.wheel_health
    if h is None:
        return
    result.extra["wheel_health"] = h
    result.metrics += [Metric(name="wheel_track_factor", value=h["track_factor"], unit="", group="slam/health",
                              note=f"effective track factor (wheel yaw / gyro yaw) +- {h['track_factor_sigma']:.3f}"),
                       Metric(name="wheel_lr_mismatch", value=h["lr_mismatch"], unit="", group="slam/health",
                              note=f"right-minus-left radius mismatch +- {h['lr_mismatch_sigma']:.4f}"),
                       Metric(name="wheel_scale_error", value=h["scale_error"], unit="", group="slam/health",
                              note=_scale_note(h) + _slip_note(h)),
                       Metric(name="wheel_rejected_fraction", value=h["rejected_fraction"], unit="",
                              group="slam/health")]
    if h["verdict"] != "ok":
        text = (f"wheel odometry {h['verdict']}: " + "; ".join(h["reasons"])
                + " - the SLAM used the wheels calibrated online; give these values to the odometry node")
        result.warnings.append(text)
        result.events.append(Event(t_s=0.0, kind="health", message=text, data={"wheel_verdict": h["verdict"]}))


def _add_imu_axes(result: RunResult, inputs: LogInputs, cfg: Config) -> None:
    """The IMU's axes in /tf_static against the machine's turns (slam/imu_axes.py), for lio: the record
    in metrics.json (`imu_axes`) and, when they look rotated, a warning and an event naming /tf_static."""
    from mrnc_eval.slam.imu_axes import imu_axes

    imu = inputs.imu
    if imu is None or cfg.slam.method != "lio" or not cfg.slam.imu_axes.enabled:
        return
    check = imu_axes(imu.stamps, imu.gyro @ _imu_in_base(inputs, cfg)[:3, :3].T, cfg.slam.imu_axes)
    result.extra["imu_axes"] = check.as_dict()
    if check.verdict == "rotated":
        text = (f"the IMU's axes look rotated in /tf_static: {check.reasons[0]}; lio read its gyro and "
                f"accelerometer in those axes - check the base_link -> {cfg.slam.sensor.lidar_frame} -> "
                f"{printable(imu.frame_id or 'IMU')} transforms, or set slam.imu.extrinsic_rot")
        result.warnings.append(text)
        result.events.append(Event(t_s=0.0, kind="health", message=text, data={"imu_axes": check.verdict}))


def _add_wheel_clock(result: RunResult, inputs: LogInputs, cfg: Config) -> None:
    """The wheel clock check (slam/wheel_clock.py): a metric, the record in metrics.json (`wheel_clock`)
    and the result, and a warning and an event when it flagged an offset."""
    clock = inputs.wheel_clock
    if clock is None:
        return
    result.extra["wheel_clock"] = clock.as_dict()
    result.metrics.append(Metric(name="wheel_time_offset_s", value=clock.offset_s, unit="s", group="slam/health",
                                 note=f"wheel stamps minus the IMU's for the same turn +- {clock.sigma_s:.4f} s "
                                      f"({clock.verdict}; {clock.applied_s:.4f} s taken out)"))
    text = clock_warning(clock, cfg.slam.wheel_odom.time_offset_s)
    if text is not None:
        result.warnings.append(text)
        result.events.append(Event(t_s=0.0, kind="health", message=text, data={"wheel_clock": clock.verdict}))


def corrected_mount(base_to_sensor: np.ndarray, rpy_deg: tuple[float, float, float]) -> np.ndarray:
    """/tf_static's base_link -> LiDAR mount with slam.sensor.mount_rpy_correction_deg right-multiplied
    (LiDAR axes); the IMU's pose in the LiDAR frame: imu_in_corrected_sensor."""
    if not any(rpy_deg):
        return base_to_sensor
    out = base_to_sensor.copy()
    out[:3, :3] = base_to_sensor[:3, :3] @ rotation.from_rpy(np.radians(rpy_deg))
    return out


def imu_in_corrected_sensor(written: np.ndarray, statics: Iterable[tuple[str, str]], *, lidar_frame: str,
                            imu_frame: str, rpy_deg: tuple[float, float, float], where: Path) -> np.ndarray:
    """The IMU's pose in the LiDAR frame once corrected_mount has turned the LiDAR by C (`written`:
    /tf_static's, `statics`: its (parent, child) edges, `where`: the log). An IMU whose path to the
    LiDAR in the tree does not pass base_link (the OS0's os_imu beside os_lidar under os_sensor)
    turns with it: kept as written. One whose path goes through base_link (a chassis IMU) stays on
    the base: C^-1 x written."""
    from mrnc_eval.io.tf_chain import frame_path

    if not any(rpy_deg) or "base_link" not in frame_path(statics, lidar_frame, imu_frame, where=where):
        return written
    out = written.copy()
    undo = rotation.from_rpy(np.radians(rpy_deg)).T
    out[:3, :3], out[:3, 3] = undo @ written[:3, :3], undo @ written[:3, 3]
    return out


def _add_mount_check(result: RunResult, est: Trajectory, inputs: LogInputs, cfg: Config) -> None:
    """The LiDAR mount's pitch and yaw error from the final trajectory's motion (slam/mount_check.py):
    metrics, the record in metrics.json (`mount_check`) and the result, and a warning when it stands out."""
    from mrnc_eval.geometry import lie
    from mrnc_eval.slam.mount_check import mount_check

    mcfg = cfg.slam.mount_check
    _add_ground_check(result, inputs, cfg)
    if not mcfg.enabled or not inputs.mount_written:  # no mount to check: the LiDAR's pose is the base's
        return
    t0 = time.process_time()
    check = mount_check(est.stamps, lie.poses(est), inputs.base_to_sensor[:3, :3], mcfg)
    cpu_ms = (time.process_time() - t0) * 1e3
    applied = inputs.applied_rpy_deg
    total = _composed_rpy(applied, check.correction_rpy_deg)
    ground = result.extra.get("mount_check", {}).get("ground")
    first = inputs.motion_mount
    result.extra["mount_check"] = {**check.as_dict(), "applied_rpy_deg": list(applied),
                                   "suggested_rpy_deg": [float(a) for a in total], "cpu_ms": cpu_ms,
                                   **({"ground": ground} if ground is not None else {}),
                                   **({"first_pass": first.as_dict()} if first is not None else {})}
    if first is not None:  # /tf_static is off although this pass ran on the corrected mount: the user fixes it
        _warn_mount(result, _mount_warning(first, np.asarray(applied), cfg, applied=inputs.mount_rpy_deg,
                                           by=_applied_by(cfg, inputs.mount_rpy_deg, motion=False), repeated=True))
    if check.verdict == "insufficient":  # too little straight motion: no numbers to show
        return
    result.metrics += [Metric(name="mount_pitch_error_deg", value=check.pitch_deg, unit="deg", group="slam/health",
                              note=f"LiDAR mount pitch error from the motion +- {check.pitch_sigma_deg:.2f} deg "
                                   f"({check.samples} samples, {check.verdict})"),
                       Metric(name="mount_yaw_error_deg", value=check.yaw_deg, unit="deg", group="slam/health",
                              note=f"LiDAR mount yaw error from the motion +- {check.yaw_sigma_deg:.2f} deg "
                                   "(with wheel factors, their hold on the lateral motion hides it)")]
    if check.verdict == "misaligned":
        _warn_mount(result, _mount_warning(check, total, cfg, applied=applied,
                                           by=_applied_by(cfg, inputs.mount_rpy_deg, motion=first is not None)))


def _warn_mount(result: RunResult, text: str) -> None:
    result.warnings.append(text)
    result.events.append(Event(t_s=0.0, kind="health", message=text, data={"mount_verdict": "misaligned"}))


def _add_ground_check(result: RunResult, inputs: LogInputs, cfg: Config) -> None:
    """The ground check of the mount at the start (slam/ground_mount.py) as `mount_check.ground` in
    metrics.json, with what was applied; a warning when it flags the mount, naming the mount it read
    through (/tf_static's, with the user's correction when set) and the whole correction."""
    g = inputs.ground_mount
    if g is None:
        return
    user = cfg.slam.sensor.mount_rpy_correction_deg
    applied = g.verdict == "misaligned" and inputs.mount_rpy_deg == g.correction_rpy_deg and not any(user)
    result.extra["mount_check"] = {"ground": {**g.as_dict(), "applied": applied}}
    if g.verdict != "misaligned":
        return
    # the check read through the user's correction: what takes the reading out is the two together
    total = _composed_rpy(user, g.correction_rpy_deg)
    value, limit = _rpy_text(total), _correction_limit(cfg)
    mount = (f"/tf_static's LiDAR mount with slam.sensor.mount_rpy_correction_deg={_rpy_text(user)}" if any(user)
             else "the LiDAR mount in /tf_static")
    kept = "the set correction kept" if any(user) else "/tf_static kept"
    if applied:
        what = (f"applied {value} deg to /tf_static's base_link -> LiDAR rotation before the run (set slam.sensor."
                "mount_rpy_correction_deg to override, slam.ground_mount.apply=false to keep /tf_static)")
    elif np.all(np.abs(total) <= limit):
        what = f"{kept}; slam.sensor.mount_rpy_correction_deg={value} would take it out"
    else:  # not a value the parameter takes
        what = (f"{kept}; correct /tf_static by {value} deg (beyond what slam.sensor.mount_rpy_correction_deg "
                f"takes: +-{limit:g} deg)")
    text = (f"the ground around the machine at the start says {mount} is off by {'; '.join(g.reasons)} "
            f"(roll/pitch, base axes; the ground's plane through that mount): {what}")
    result.warnings.append(text)
    result.events.append(Event(t_s=0.0, kind="health", message=text, data={"ground_mount_verdict": g.verdict}))


def _composed_rpy(first: Iterable[float], then: Iterable[float]) -> np.ndarray:
    """Roll, pitch, yaw (deg) of the rotation `first` right-multiplied by `then` (both deg, as the mount
    corrections are applied: the one a check read through, then its own reading)."""
    r = rotation.from_rpy(np.radians(list(first))) @ rotation.from_rpy(np.radians(list(then)))
    return np.degrees(rotation.rpy(r)) + 0.0  # no -0.0


def _rpy_text(rpy: Iterable[float]) -> str:
    """Roll, pitch, yaw (deg) as the config writes them: [0.00, -0.42, 0.50]."""
    return "[" + ", ".join(f"{a:.2f}" for a in rpy) + "]"


def _correction_limit(cfg: Config) -> float:
    """The largest angle slam.sensor.mount_rpy_correction_deg takes (its declared range), deg."""
    param = next(f for f in dataclasses.fields(cfg.slam.sensor) if f.name == "mount_rpy_correction_deg")
    return float(param.metadata["bounds"]["le"])


def _applied_by(cfg: Config, before: tuple[float, float, float], *, motion: bool) -> str:
    """Who turned /tf_static's mount before the run: the user's correction or else the ground check
    (by `before`, deg), and (`motion`) a first pass's motion check."""
    who = ["slam.sensor.mount_rpy_correction_deg" if any(cfg.slam.sensor.mount_rpy_correction_deg)
           else "the ground check"] if any(before) else []
    return " and ".join(who + (["the first pass's motion (slam.mount_check.apply)"] if motion else []))


def _mount_warning(check: MountCheck, total: np.ndarray, cfg: Config, *,
                   applied: tuple[float, float, float] = (0.0, 0.0, 0.0), by: str = "the ground check",
                   repeated: bool = False) -> str:
    """The misaligned mount check's warning, with the slam.sensor.mount_rpy_correction_deg that undoes it
    (`total`: the applied correction and the check's, deg) when the parameter's range admits it; the
    mount named is the one the motion was read through (/tf_static's turned by `applied`, deg, `by`
    whom). `repeated`: `check` is a first pass's, and the run was repeated on the corrected mount."""
    limit = _correction_limit(cfg)
    mount = (f"the LiDAR mount (/tf_static's turned by {_rpy_text(applied)} deg by {by} before the run)"
             if any(applied) else "the LiDAR mount in /tf_static")
    value = _rpy_text(total)
    fix = (f"correct /tf_static or set slam.sensor.mount_rpy_correction_deg={value}" if np.all(np.abs(total) <= limit)
           else f"correct /tf_static (by {value} deg, beyond what slam.sensor.mount_rpy_correction_deg takes: "
           f"+-{limit:g} deg)")
    carried = ("the run was repeated on the mount corrected by that (slam.mount_check.apply): its base_link poses, "
               "wheel and GNSS factors read the corrected mount" if repeated
               else "base_link poses and the end drift carry it")
    return (f"{mount} looks off by {'; '.join(check.reasons)} (the machine's motion, "
            f"{check.distance_m:.0f} m of it, is off its base x axis by that much; roll is not observable): "
            f"{carried}; {fix}")


def _scale_note(h: dict[str, Any]) -> str:
    """What the wheel scale error was measured against (wheel_health's scale_source)."""
    sigma = f" +- {h['scale_error_sigma']:.4f}"
    source = h.get("scale_source", "lidar")
    if source == "prior":
        return f"not measured (no LiDAR distance step, no GNSS spread): the prior, 0{sigma}"
    against = "LiDAR distance" if source == "lidar" else "GNSS distance, read after the run (not used by it)"
    return f"wheel distance / {against} - 1{sigma}"


def _slip_note(h: dict[str, Any]) -> str:
    """The distance steps the scale fit put down to slip (soft or wet ground), not to calibration."""
    if not h.get("slip_steps"):
        return ""
    return (f" ({h['scale_steps']} straight steps; {h['slip_steps']} more left out as slip, the wheels over-reading "
            f"the LiDAR by {h['slip_mean_over_read'] * 100:.0f} % there)")


def _add_map_quality(result: RunResult, out: SlamOutput, cfg: Config) -> None:
    q = out.map_quality
    if q is None:
        return
    r = cfg.slam.map_quality.radius_m
    result.metrics += [Metric(name="map_entropy", value=q.mean_map_entropy, unit="nats", group="slam/map",
                              note=f"mean map entropy: mean of 0.5 ln det(2 pi e Sigma) over map points, Sigma = "
                                   f"covariance of the points within {r:g} m (lower = sharper map)"),
                       Metric(name="map_plane_variance_m2", value=q.mean_plane_variance_m2, unit="m^2",
                              group="slam/map",
                              note=f"mean plane variance: mean smallest eigenvalue of Sigma within {r:g} m")]
    result.extra["map_quality"] = {"radius_m": r, "points_evaluated": q.points_evaluated,
                                   "cloud": "union of the keyframe feature clouds in their final poses"}


def _write_files(result: RunResult, out_dir: Path, cfg: Config, trajectories: dict[str, Trajectory],
                 map_points: np.ndarray) -> None:
    """Trajectories (TUM; KITTI too), the map (PLY, PCD), metrics.json and the result, written atomically."""
    from mrnc_eval.io.trajectory_files import write_kitti, write_tum

    tmp = Path(tempfile.mkdtemp(prefix=".slam-files-"))
    try:
        files = {}
        for name, trajectory in trajectories.items():
            write_tum(tmp / name, trajectory)
            files[name] = tmp / name
        if "trajectory.tum" in trajectories:  # the same poses as KITTI rows (line k = line k of the TUM file)
            write_kitti(tmp / "trajectory.kitti", trajectories["trajectory.tum"])
            files["trajectory.kitti"] = tmp / "trajectory.kitti"
        if map_points.size:
            from mrnc_eval.io.pcd import write_pcd_xyz
            from mrnc_eval.io.ply import write_ply_xyz

            write_ply_xyz(tmp / "map.ply", map_points)
            write_pcd_xyz(tmp / "map.pcd", map_points)
            files["map.ply"], files["map.pcd"] = tmp / "map.ply", tmp / "map.pcd"
        metrics: dict[str, object] = {m.name: {"value": m.value, "unit": m.unit} for m in result.metrics}
        for key in ("wheel_health", "wheel_clock", "imu_axes", "mount_check"):
            if key in result.extra:
                metrics[key] = result.extra[key]
        (tmp / "metrics.json").write_text(json.dumps(json_safe(metrics), indent=2), encoding="utf-8")
        files["metrics.json"] = tmp / "metrics.json"
        write_result(result, out_dir, dump_config(cfg), files)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


SLAM_OUTPUT_BYTES = 200_000_000  # free space asked for per log before a run: map (PLY + PCD), trajectories


def _row_ids(logs: list[Path]) -> dict[Path, str]:
    """Table I row labels: the log id, or the id of its folder and name when two logs share a
    name (a/run.mcap and b/run.mcap are two rows, not one row shown twice)."""
    names = [log_id_for(p) for p in logs]
    return {p: stable_id(Path(p.parent.name) / p.name) if names.count(n) > 1 else n
            for p, n in zip(logs, names, strict=True)}


def main(logs: list[Path], cfg: Config, *, method: str | None, out: Path, no_loop: bool, no_gps: bool,
         json_out: bool, topic: str | None = None, window: SweepWindow | None = None) -> None:
    """The `slam` verb: the CLI flags set config values (slam.method, slam.loop.enabled,
    slam.gps.enabled, --topic: io.roles.lidar), which are then the one source of truth; `window`
    limits the sweeps read (recorded in each result's extra and warnings)."""
    from mrnc_eval.errors import SomeInputsFailed
    from mrnc_eval.io.scan_folder import is_scan_folder

    cfg = with_method(cfg, method)
    if topic is not None:
        cfg = replace_path(cfg, "io.roles", {**cfg.io.roles, "lidar": topic})
    if no_loop:
        cfg = replace_path(cfg, "slam.loop.enabled", False)
    if no_gps:
        cfg = replace_path(cfg, "slam.gps.enabled", False)
    from mrnc_eval.io.containers import detect_container

    for path in logs:  # a folder of logs (not a ROS 2 bag, not scans) is refused before anything is written
        if path.is_dir() and not is_scan_folder(path):
            detect_container([path])
    check_output_root(out, need_bytes=SLAM_OUTPUT_BYTES * len(logs))  # before the long work, not after it
    results: list[tuple[Path, RunResult]] = []
    failed: list[tuple[Path, str]] = []
    cells: dict[tuple[str, str], Cell] = {}  # (log row, method) -> APE cell of Table I
    row_ids = _row_ids(logs)
    for path in logs:
        run_dir = new_run_dir(out, log_id_for(path), f"slam-{cfg.slam.method}")
        try:
            if is_scan_folder(path):  # kiss-icp's habit: a folder of .bin/.pcd scans with timestamps.txt
                r = run_scan_folder(path, cfg, run_dir, window=window)
            else:
                r = run_log(path, cfg, run_dir, progress=True, window=window)
        except InputError as err:
            if len(logs) == 1:
                raise
            failed.append((path, str(err)))
            cells[(row_ids[path], cfg.slam.method)] = Cell(None, str(err))
            continue
        results.append((run_dir, r))
        link_latest(run_dir)
        m = r.metric(TABLE_METRIC[cfg.slam.table_trajectory])
        cells[(row_ids[path], cfg.slam.method)] = Cell(m.value if m else None, "" if m else "no ground truth")
    _print_summary(results, cells, [row_ids[p] for p in logs], cfg, json_out)
    if failed:
        raise SomeInputsFailed("; ".join(f"{p}: {e}" for p, e in failed))
    raise_on_failed_gates([r for _, r in results], cfg.gates)


def _print_summary(results: list[tuple[Path, RunResult]], cells: dict[tuple[str, str], Cell], rows: list[str],
                   cfg: Config, json_out: bool) -> None:
    from mrnc_eval.reports.tables import render_table

    if json_out:
        from mrnc_eval.commands.output import emit_json, item

        emit_json("slam", [item(r.log_id, {m.name: m.value for m in r.metrics}, log=r.log_path, run_dir=str(d),
                                method=r.extra.get("method"), units={m.name: m.unit for m in r.metrics},
                                mapping=mapping_rate(r), warnings=list(r.warnings))
                           for d, r in results],
                  meta={"table_trajectory": cfg.slam.table_trajectory},
                  warnings=[f"{r.log_id}: {w}" for _, r in results for w in r.warnings])
        return
    for d, r in results:
        vals = {m.name: m.value for m in r.metrics}
        apes = [f"{label} {vals[name]:.4f} m" for label, name in (("online", "ape_online_rmse_m"),
                                                                    ("smoothed", "ape_rmse_m")) if name in vals]
        ape = ", ".join(apes) if apes else f"n/a (no ground truth: {ground_truth_hint(Path(r.log_path))})"
        if not apes and "ape_gnss_rmse_m" in vals:  # the comparison the run could make without ground truth
            ape += f"; vs GNSS {vals['ape_gnss_rmse_m']:.3f} m (2-D, includes the GNSS error)"
        used = ", ".join(f"{role} {topic}" for role, topic in r.extra.get("roles", {}).items())
        line = (f"{r.log_id} ({used}): APE RMSE {ape}, RTF {vals['rtf']:.2f} ({mapping_rate(r)}), "
                f"{vals['keyframes']} keyframes, {vals['loop_closures']} loop closures -> {d}")
        sys.stdout.write(printable(line) + "\n")  # topic names come from the log
        for warning in r.warnings:  # the run's findings (a sensor that let it down) where the user looks
            log.warning("%s: %s", r.log_id, warning)
    if len(rows) > 1:
        title = f"APE RMSE (SE(3) aligned, {cfg.slam.table_trajectory} trajectory)"
        sys.stdout.write(render_table(table_one(cells, rows, [cfg.slam.method], title=title),
                                      "markdown"))


def mapping_rate(r: RunResult) -> str:
    """What the RTF measured: how many sweeps were mapped (a RTF means nothing without it)."""
    return str(r.extra.get("mapping_rate", "mapping rate unknown"))
