"""Generate a synthetic log: drive the mission in closed loop, sample every sensor from the
ground truth, and write it the way the robot's drivers do (real bag writers, stamp order).
Deterministic: one seeded generator, consumed in a fixed order, and a fixed log epoch."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import ClosedLoopTrace, run_closed_loop
from mrnc_eval.control.scenario import Scenario, scripted_scenario
from mrnc_eval.data import ImuSeries, Trajectory, Waypoints
from mrnc_eval.errors import ConfigError, UsageError
from mrnc_eval.io.ground_truth import gt_tum_path
from mrnc_eval.io.trajectory_files import write_tum
from mrnc_eval.io.writers import Format, LogWriter
from mrnc_eval.sim.config import FieldConfig, LidarSimConfig
from mrnc_eval.sim.gnss import GnssFixes, simulate_field_gnss, simulate_gnss
from mrnc_eval.sim.imu import ImuNoise, field_imu, simulate_imu
from mrnc_eval.sim.lidar import BodyBox, FieldLidar, LidarSimulator, OrganisedSweep, ouster_metadata
from mrnc_eval.sim.lidar_field import place_moving_box, scatter_puddles
from mrnc_eval.sim.scene import SCENES, Scene, build_scene
from mrnc_eval.sim.standstill import hold_start
from mrnc_eval.sim.trajectory import BASE_HEIGHT_M, BodyTrajectory, stone_shake
from mrnc_eval.sim.wheels import WheelErrors, draw_wheel_errors, drive_signals

LOG_EPOCH_S = 1_763_800_000.0  # sensor-clock time of every simulated log's t = 0, s
LIDAR_MODELS = {"os0-128": 128, "os0-64": 64, "os0-32": 32}
PATHS = ("circle", "figure8", "loop", "line")
Profile = Literal["ideal", "field"]
PROFILES: tuple[Profile, ...] = ("ideal", "field")
WHEEL_STREAM, GNSS_STREAM = 17, 19  # the wheel errors and a forced GNSS mode draw from streams of their own
FIELD_STREAM = 13  # the field profile draws from default_rng([seed, FIELD_STREAM]): ideal draws stay as they were
TOPICS = {"lidar": "/ouster/points", "metadata": "/ouster/metadata", "imu": "/ouster/imu",
          "chassis_imu": "/chassis/imu", "gnss": "/gnss/fix", "wheels": "/wheel_speeds", "pumps": "/pump_cmd",
          "cmd_vel": "/cmd_vel", "wheel_odom": "/wheel_odom", "plan": "/plan", "ground_truth": "/ground_truth",
          "sim_errors": "/sim/errors_drawn"}


@dataclass(frozen=True)
class SimRequest:
    scene: str = "yard"
    path: str = "circle"  # circle = the paper's mission; figure8, loop, line are scripted
    duration_s: float | None = None  # None: until the path is done
    lidar: str = "os0-128"
    columns: int = 1024
    rate_hz: float = 10.0
    fmt: str = "mcap"
    seed: int | None = None  # None: cfg.sim.seed
    profile: str | None = None  # ideal or field; None: cfg.sim.profile


def mounts(cfg: Config) -> tuple[np.ndarray, np.ndarray]:
    """(written, true) base_link -> os_sensor: /tf_static carries the nominal mount; with the field
    profile the LiDAR (and the IMU inside it) really sits at nominal x calibration error."""
    written = transform(cfg.sim.lidar.mount_xyz_m)
    if cfg.sim.profile != "field":
        return written, written
    cal = cfg.sim.field.calibration
    error = transform(cal.lidar_xyz_error_m, Rotation.from_euler("xyz", cal.lidar_rpy_error_deg, degrees=True)
                      .as_matrix())
    true = written.copy()
    true[:3, :3] = written[:3, :3] @ error[:3, :3]
    true[:3, 3] = written[:3, 3] + error[:3, 3]
    return written, true


def transform(xyz: Sequence[float], rot: np.ndarray | None = None) -> np.ndarray:
    """4x4 pose from a translation (m) and a rotation matrix (identity when None)."""
    t = np.eye(4)
    t[:3, 3] = xyz
    if rot is not None:
        t[:3, :3] = rot
    return t


def validate(req: SimRequest) -> None:
    problems = []
    if req.scene not in SCENES:
        problems.append(f"scene {req.scene!r} (choose from {', '.join(SCENES)})")
    if req.path not in PATHS:
        problems.append(f"path {req.path!r} (choose from {', '.join(PATHS)})")
    if req.lidar not in LIDAR_MODELS:
        problems.append(f"LiDAR {req.lidar!r} (choose from {', '.join(LIDAR_MODELS)})")
    if req.columns not in (512, 1024, 2048) or req.rate_hz not in (10.0, 20.0):
        problems.append(f"{req.columns} columns at {req.rate_hz:g} Hz (OS0: 512/1024/2048 at 10 or 20 Hz)")
    if req.columns * req.rate_hz > 20480:
        problems.append("2048 columns only at 10 Hz (OS0 modes)")
    if req.fmt not in ("mcap", "db3", "bag"):
        problems.append(f"format {req.fmt!r} (mcap, db3 or bag)")
    if req.profile is not None and req.profile not in PROFILES:
        problems.append(f"profile {req.profile!r} (ideal or field)")
    if req.duration_s is not None and req.duration_s <= 0.5:
        problems.append(f"duration {req.duration_s:g} s (must exceed 0.5 s)")
    if problems:
        raise UsageError("unsupported simulation request: " + "; ".join(problems))


def check_lidar_sets(cfg: Config, req: SimRequest) -> None:
    """--lidar, --columns and --rate set the sensor's beams, columns and rate, whatever
    sim.lidar.* says: a --set of those keys that the options would silently override is refused
    (`--set sim.lidar.rate_hz=20` with the default --rate wrote a 10 Hz log)."""
    from mrnc_eval.sim.config import LidarSimConfig

    default, given = LidarSimConfig(), cfg.sim.lidar
    models = {beams: name for name, beams in LIDAR_MODELS.items()}
    wanted = {"beams": ("--lidar", LIDAR_MODELS.get(req.lidar)), "columns": ("--columns", req.columns),
              "rate_hz": ("--rate", req.rate_hz)}
    problems = []
    for key, (option, value) in wanted.items():
        asked = getattr(given, key)
        if value is not None and asked != getattr(default, key) and asked != value:
            use = models.get(int(asked), f"(no OS0 has {asked:g} beams)") if key == "beams" else f"{asked:g}"
            problems.append(f"sim.lidar.{key}={asked:g} is set by {option} ({value:g}): use {option} {use}")
    if problems:
        raise UsageError("; ".join(problems))


def _driven_path(trace: ClosedLoopTrace) -> np.ndarray:
    """The driven xy (m) every ~0.1 m: what the scene must leave clear."""
    xy = np.c_[trace.x, trace.y]
    step = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
    return np.asarray(xy[np.unique(np.searchsorted(step, np.arange(0.0, step[-1] + 0.1, 0.1)).clip(0, len(xy) - 1))])


def simulate_log(out: Path, cfg: Config, req: SimRequest,
                 progress: Callable[[int, int], None] | None = None) -> Path:
    """Write the log to `out` (atomically) and the ground truth TUM beside it; returns the log
    path. `progress(done, total)` is called after each recorded sweep. The table of contents of a
    recording: world, motion, then every sensor in a fixed draw order (the order is the format:
    the same seed writes the same bytes)."""
    validate(req)
    if not cfg.sim.scene_scale > 0:
        raise ConfigError(f"sim.scene_scale must be > 0, got {cfg.sim.scene_scale:g}")
    if req.profile is not None:
        cfg = replace(cfg, sim=replace(cfg.sim, profile=cast(Profile, req.profile)))  # validate() checked it
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    seed = cfg.sim.seed if req.seed is None else req.seed
    run = _Run(cfg=cfg, req=req, rng=np.random.default_rng(seed), frng=np.random.default_rng([seed, FIELD_STREAM]),
               lcfg=replace(cfg.sim.lidar, beams=LIDAR_MODELS[req.lidar], columns=req.columns, rate_hz=req.rate_hz))
    world = _drive_world(run, seed)
    frames = _Frames.of(cfg, run.lcfg)
    compression = None if cfg.sim.bag_compression == "none" else cfg.sim.bag_compression
    writer = LogWriter(out, cast(Format, req.fmt), ros1_compression=compression)  # validate() checked it
    try:
        _write_static(writer, run, world, frames)
        _write_imus(writer, run, world, frames)
        fixes = _write_gnss(writer, run, world, frames, np.random.default_rng([seed, GNSS_STREAM]))
        errors_on = cfg.sim.wheels.model == "errors" or (cfg.sim.wheels.model == "profile" and run.field is not None)
        wheel_errors = draw_wheel_errors(cfg.sim.wheels, errors_on, np.random.default_rng([seed, WHEEL_STREAM]))
        _write_drive(writer, world.trace, run.stamps(cfg.sim.wheel_rate_hz, world), cfg, LOG_EPOCH_S, run.host_stamps,
                     wheel_errors, np.random.default_rng([seed, WHEEL_STREAM, 1]), latency_s=_wheel_latency(cfg))
        drawn = _errors_drawn(cfg, wheel_errors, fixes, world.trace)
        writer.write_strings(TOPICS["sim_errors"], np.array([LOG_EPOCH_S]), [json.dumps(drawn, sort_keys=True)])
        gt = _write_ground_truth(writer, world.traj, run.stamps(cfg.sim.ground_truth_rate_hz, world), LOG_EPOCH_S)
        _write_sweeps(writer, run, world, frames, progress)
        path = writer.close()
    except BaseException:
        writer.abort()
        raise
    write_tum(gt_tum_path(path), gt)
    errors_json_path(path).write_text(json.dumps(drawn, indent=2, sort_keys=True), encoding="utf-8")
    return path


@dataclass(frozen=True, kw_only=True)
class _Run:
    """One recording's settings and random streams (rng: the ideal draws; frng: the field profile's)."""

    cfg: Config
    req: SimRequest
    rng: np.random.Generator
    frng: np.random.Generator
    lcfg: LidarSimConfig

    @property
    def field(self) -> FieldConfig | None:
        return self.cfg.sim.field if self.cfg.sim.profile == "field" else None

    def stamps(self, rate: float, world: _World) -> np.ndarray:
        """Sample times (s since the log start) of a sensor at `rate` Hz."""
        return np.arange(0.0, world.t_end, 1.0 / rate)

    def host_stamps(self, times: np.ndarray) -> np.ndarray:
        """Header stamps of host-stamped topics (log time): jittered with the field profile."""
        field = self.field
        return times if field is None else times + self.frng.normal(0.0, field.clock.host_jitter_s, times.size)


@dataclass(frozen=True, kw_only=True)
class _World:
    """The driven mission and the world it crossed."""

    scenario: Scenario
    trace: ClosedLoopTrace
    centre: tuple[float, float]  # the waypoints' mean, m
    scene: Scene
    traj: BodyTrajectory
    t_end: float  # s


def _drive_world(run: _Run, seed: int) -> _World:
    """Drive the mission in closed loop, build the scene clear of the driven path, and the body's
    motion over its terrain (stones shake it with the field profile)."""
    cfg, req, scfg, field = run.cfg, run.req, run.cfg.sim, run.field
    scenario = scripted_scenario(req.path, cfg.control, size_m=scfg.path_size_m)
    still = max(scfg.standstill_s, 0.0)
    drive_s = None if req.duration_s is None else max(req.duration_s - still, 0.5)
    trace = hold_start(run_closed_loop(scenario, cfg.control, cfg.robot, "raid", duration_s=drive_s, seed=seed),
                       still)
    centre = tuple(scenario.waypoints_xy.mean(axis=0))
    roughness = scfg.terrain_roughness_m if field is None else field.world.terrain_roughness_m
    scene = build_scene(req.scene, seed=seed, amplitude_m=scfg.terrain_amplitude_m, roughness_m=roughness,
                        centre=centre, keep_clear_xy=_driven_path(trace), clearance_m=cfg.robot.width_m / 2 + 0.5,
                        scale=scfg.scene_scale)
    shake = None
    if field is not None:
        w = field.world
        shake = stone_shake(np.asarray(trace.t, float), np.c_[trace.x, trace.y], stones_per_m=w.stones_per_m,
                            height_m=w.stone_height_m, length_m=w.stone_length_m, track_m=cfg.robot.track_width_m,
                            wheelbase_m=w.wheelbase_m, natural_hz=w.shake_hz, damping=w.shake_damping, rng=run.frng)
    traj = BodyTrajectory.from_trace(trace, scene.terrain, shake, scfg.motion_smoothing_s)
    t_end = float(trace.t[-1]) if req.duration_s is None else float(req.duration_s)
    return _World(scenario=scenario, trace=trace, centre=centre, scene=scene, traj=traj, t_end=t_end)


@dataclass(frozen=True, kw_only=True)
class _Frames:
    """The mounts (4x4): as /tf_static writes them, and where the sensors really are."""

    base_to_sensor: np.ndarray  # written
    true_base_to_sensor: np.ndarray
    sensor_to_lidar: np.ndarray
    sensor_to_imu: np.ndarray
    base_to_gnss: np.ndarray
    base_to_chassis: np.ndarray

    @classmethod
    def of(cls, cfg: Config, lcfg: LidarSimConfig) -> _Frames:
        written, true = mounts(cfg)
        scfg = cfg.sim
        return cls(base_to_sensor=written, true_base_to_sensor=true,
                   sensor_to_lidar=transform((0.0, 0.0, lcfg.lidar_to_sensor_z_m),
                                             Rotation.from_euler("z", math.pi).as_matrix()),
                   sensor_to_imu=transform(scfg.imu.mount_xyz_m), base_to_gnss=transform(scfg.gnss.antenna_xyz_m),
                   base_to_chassis=transform(scfg.imu.chassis_mount_xyz_m, Rotation.from_euler(
                       "xyz", scfg.imu.chassis_mount_rpy_deg, degrees=True).as_matrix()))

    @property
    def base_to_imu(self) -> np.ndarray:
        return self.true_base_to_sensor @ self.sensor_to_imu


def _write_static(writer: LogWriter, run: _Run, world: _World, frames: _Frames) -> None:
    """/tf_static, the Ouster metadata and the planned path, at the log start."""
    f, t0 = frames, LOG_EPOCH_S
    writer.write_tf_static([("base_link", "os_sensor", f.base_to_sensor), ("os_sensor", "os_lidar", f.sensor_to_lidar),
                            ("os_sensor", "os_imu", f.sensor_to_imu), ("base_link", "chassis_imu", f.base_to_chassis),
                            ("base_link", "gnss", f.base_to_gnss)], t0)
    writer.write_strings(TOPICS["metadata"], np.array([t0]),
                         [ouster_metadata(run.lcfg, f.sensor_to_imu, run.req.lidar)])
    writer.write_path(TOPICS["plan"], Waypoints(world.scenario.waypoints_xy, frame_id="map"), t0)


def _write_imus(writer: LogWriter, run: _Run, world: _World, frames: _Frames) -> None:
    """The Ouster IMU (the profile's model) and the chassis IMU (an ADIS16475-class part: the
    ideal model in both profiles)."""
    scfg, field = run.cfg.sim, run.field
    if field is None:
        noise = ImuNoise.from_config(scfg.imu)
        imu = simulate_imu(world.traj, run.stamps(scfg.imu.rate_hz, world), frames.base_to_imu, noise, run.rng,
                           "os_imu")
    else:
        noise = ImuNoise(field.imu.acc_noise_density, field.imu.gyro_noise_density, field.imu.acc_bias_walk,
                         field.imu.gyro_bias_walk)
        imu = _field_imu_series(world.traj, run.stamps(scfg.imu.rate_hz, world), frames.base_to_imu, run.cfg,
                                run.frng)
    _write_imu(writer, TOPICS["imu"], imu, noise, LOG_EPOCH_S)
    if scfg.imu.chassis_rate_hz > 0:
        chassis_noise = ImuNoise.from_config(scfg.imu)
        chassis = simulate_imu(world.traj, run.stamps(scfg.imu.chassis_rate_hz, world), frames.base_to_chassis,
                               chassis_noise, run.rng, "chassis_imu")
        _write_imu(writer, TOPICS["chassis_imu"], chassis, chassis_noise, LOG_EPOCH_S)


def _write_gnss(writer: LogWriter, run: _Run, world: _World, frames: _Frames,
                forced_rng: np.random.Generator) -> GnssFixes:
    """GNSS fixes: ideal, or the field receiver (fix types, multipath near structures, stamped late);
    sim.gnss.mode rtk/float/single forces one fix type (in the ideal profile from `forced_rng`, so
    the ideal draws stay)."""
    scfg, field = run.cfg.sim, run.field
    times = run.stamps(scfg.gnss.rate_hz, world)
    if field is None and scfg.gnss.mode == "profile":
        fixes = simulate_gnss(world.traj, times, frames.base_to_gnss, scfg.gnss, run.rng)
        gnss_stamps = fixes.stamps
    else:
        fixes = simulate_field_gnss(world.traj, times, frames.base_to_gnss, scfg.gnss, scfg.field.gnss,
                                    _structures_xy(world.scene), run.frng if field is not None else forced_rng)
        gnss_stamps = fixes.stamps if field is None else run.host_stamps(fixes.stamps + field.clock.gnss_latency_s)
    writer.write_navsatfix(TOPICS["gnss"], gnss_stamps + LOG_EPOCH_S, fixes.lla, fixes.covariance, fixes.status)
    return fixes


def _write_sweeps(writer: LogWriter, run: _Run, world: _World, frames: _Frames,
                  progress: Callable[[int, int], None] | None) -> None:
    """The LiDAR sweeps ray-cast against the scene, the recorded ones (throttled outside the full-rate window)."""
    cfg, lcfg, field = run.cfg, run.lcfg, run.field
    body = _body_box(cfg) if lcfg.self_occlusion or (field is not None and field.lidar.body_in_cloud) else None
    lidar = LidarSimulator(world.scene, lcfg, frames.true_base_to_sensor, run.rng, body,
                           None if field is None else _field_lidar(cfg, world.scene, world.trace, world.centre,
                                                                   run.frng))
    kept = recorded_sweep_starts(world.t_end, lcfg)
    for n, start in enumerate(kept):
        s = lidar.sweep(world.traj, float(start))
        stamp = s.stamp if field is None else s.stamp + run.frng.normal(0.0, field.clock.lidar_jitter_s)
        _write_cloud(writer, LOG_EPOCH_S + stamp, s, lcfg)
        if progress is not None:
            progress(n + 1, kept.size)


def recorded_sweep_starts(t_end: float, lcfg: LidarSimConfig) -> np.ndarray:
    """Start times (s) of the sweeps written: every n-th (a throttled recording), plus every sweep
    inside the full-rate window."""
    starts = np.arange(0.0, t_end - 1.0 / lcfg.rate_hz, 1.0 / lcfg.rate_hz)
    keep = np.arange(starts.size) % max(1, lcfg.record_every) == 0
    if lcfg.full_rate_window_s is not None:
        a, b = lcfg.full_rate_window_s
        keep |= (starts >= a) & (starts < b)
    return starts[keep]


def _write_cloud(writer: LogWriter, stamp: float, s: OrganisedSweep, lcfg: LidarSimConfig) -> None:
    """One sweep in the configured layout, coordinates rounded to `xyz_step_m` (no return stays 0)."""
    xyz = s.xyz if lcfg.xyz_step_m <= 0 else (np.round(s.xyz / lcfg.xyz_step_m) * lcfg.xyz_step_m).astype(np.float32)
    if lcfg.cloud_layout == "organised":
        writer.write_ouster_cloud(TOPICS["lidar"], stamp, xyz, s.t_ns, s.range_mm, s.reflectivity, s.intensity,
                                  s.ambient)
        return
    ret = s.range_mm > 0  # (H, W) pixels with a return, ring-major like the organised cloud
    ring = np.broadcast_to(np.arange(ret.shape[0], dtype=np.uint16)[:, None], ret.shape)
    writer.write_returns_cloud(TOPICS["lidar"], stamp, xyz[ret], s.t_ns[ret], s.intensity[ret], ring[ret])


def _field_imu_series(traj: BodyTrajectory, times: np.ndarray, base_to_imu: np.ndarray, cfg: Config,
                      rng: np.random.Generator) -> ImuSeries:
    """The Ouster IMU of the field profile with its header stamps: true time + constant offset + jitter."""
    clock = cfg.sim.field.clock
    s = field_imu(traj, times, base_to_imu, cfg.sim.field.imu, rng)
    header = s.times + clock.imu_offset_s + rng.normal(0.0, clock.imu_jitter_s, s.times.size)
    return ImuSeries(header, s.acc, s.gyro, None, "os_imu")


def _structures_xy(scene: Scene) -> np.ndarray:
    """Horizontal positions of every object vertex (not the ground): what shades and reflects GNSS."""
    parts = [v[:, :2] for v in scene.vertices[1:]]
    return np.concatenate(parts).astype(float) if parts else np.zeros((0, 2))


def _field_lidar(cfg: Config, scene: Scene, trace: ClosedLoopTrace, centre: tuple[float, float],
                 rng: np.random.Generator) -> FieldLidar:
    w = cfg.sim.field.world
    puddles = scatter_puddles(centre, 30.0 * cfg.sim.scene_scale, cfg.sim.field.lidar, rng)
    moving = None
    if w.moving_object != "none":
        moving = place_moving_box(w.moving_object, np.c_[trace.x, trace.y], np.asarray(trace.t, float), centre,
                                  w.moving_speed_mps, w.moving_clearance_m, cfg.robot.length_m / 2, rng)
    return FieldLidar(cfg.sim.field.lidar, puddles, moving, rng)


def _body_box(cfg: Config) -> BodyBox:
    """The machine's body in base_link: footprint length x width, from the ground clearance to its height."""
    r, clearance = cfg.robot, cfg.sim.lidar.body_clearance_m
    bottom, top = clearance - BASE_HEIGHT_M, r.height_m - BASE_HEIGHT_M
    return BodyBox((0.0, 0.0, 0.5 * (bottom + top)), (r.length_m, r.width_m, top - bottom))


def _write_imu(writer: LogWriter, topic: str, imu: ImuSeries, noise: ImuNoise, t0: float) -> None:
    acc_var, gyro_var = noise.variances(1.0 / float(np.median(np.diff(imu.stamps))) if imu.stamps.size > 1 else 100.0)
    writer.write_imu(topic, replace(imu, stamps=imu.stamps + t0), acc_var=acc_var, gyro_var=gyro_var)


def _errors_drawn(cfg: Config, wheels: WheelErrors, fixes: GnssFixes, trace: ClosedLoopTrace) -> dict[str, Any]:
    """What the log's sensors got wrong on purpose, for tests and benchmarks (the /sim/errors_drawn
    topic, a std_msgs/String of JSON, and <log>.errors.json beside the log), and the drive's safety stops
    (RAID's barrier: the machine then stands for the rest of the log)."""
    status, counts = np.unique(np.asarray(fixes.status), return_counts=True)
    drawn: dict[str, Any] = {
        "profile": cfg.sim.profile, "wheels": wheels.as_dict(), "track_width_m": cfg.robot.track_width_m,
        "gnss": {"mode": cfg.sim.gnss.mode, "outages_s": [list(o) for o in cfg.sim.gnss.outages_s],
                 "status_counts": {str(int(s)): int(c) for s, c in zip(status, counts, strict=True)}}}
    latency = _wheel_latency(cfg)
    if latency:  # only then: the logs made before keep their bytes
        drawn["clock"] = {"wheel_latency_s": latency}
    stops = [e for e in trace.events if e.get("kind") == "safety_stop"]
    if stops:  # likewise
        drawn["drive"] = {"safety_stops": stops, "completed": bool(trace.completed)}
    return drawn


def _wheel_latency(cfg: Config) -> float:
    """sim.field.clock.wheel_latency_s with the field profile, else 0 (s)."""
    return cfg.sim.field.clock.wheel_latency_s if cfg.sim.profile == "field" else 0.0


def errors_json_path(log_path: Path) -> Path:
    """`<log name without suffix>.errors.json` beside the log (next to the .gt.tum)."""
    gt = gt_tum_path(log_path)
    return gt.with_name(gt.name.removesuffix(".gt.tum") + ".errors.json")


def _write_drive(writer: LogWriter, trace: ClosedLoopTrace, times: np.ndarray, cfg: Config, t0: float,
                 stamp: Callable[[np.ndarray], np.ndarray], errors: WheelErrors | None = None,
                 rng: np.random.Generator | None = None, *, latency_s: float = 0.0) -> None:
    """Drive-train topics; `stamp` maps true times to header stamps (the identity when ideal);
    the wheel speeds and odometry carry `errors` (sim.wheels) and are stamped `latency_s` late."""
    d = drive_signals(trace, times, cfg.robot.wheel_radius_m, cfg.robot.track_width_m, errors, rng)
    header = stamp(d.stamps) + t0
    measured = stamp(d.stamps + latency_s) + t0 if latency_s else header
    writer.write_joint_state(TOPICS["wheels"], measured, ["left_wheel", "right_wheel"], d.wheel_rad_s)
    writer.write_joint_state(TOPICS["pumps"], header, ["left_pump", "right_pump"], d.pump_rpm)
    writer.write_twist_stamped(TOPICS["cmd_vel"], replace(d.cmd_vel, stamps=header))
    zero = np.zeros_like(d.odom_v)
    writer.write_odometry(TOPICS["wheel_odom"], replace(d.odometry, stamps=measured), "odom",
                          "base_link", linear_velocity=np.c_[d.odom_v, zero, zero],
                          angular_velocity=np.c_[zero, zero, d.odom_omega])


def _write_ground_truth(writer: LogWriter, traj: BodyTrajectory, times: np.ndarray, t0: float) -> Trajectory:
    p, rot = traj.pose(times)
    v_world, w_body = traj.velocity(times)
    gt = Trajectory(times + t0, p, rot.as_quat(), name="ground_truth", frame_id="map", child_frame_id="base_link")
    # nav_msgs/Odometry twist is in the child frame (base_link)
    writer.write_odometry(TOPICS["ground_truth"], gt, "map", "base_link", linear_velocity=rot.inv().apply(v_world),
                          angular_velocity=w_body)
    return gt
