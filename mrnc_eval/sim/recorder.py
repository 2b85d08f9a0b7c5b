"""Generate a synthetic log: drive the mission in closed loop, sample every sensor from the
ground truth, and write it the way the robot's drivers do (real bag writers)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mrnc_eval.config import Config
from mrnc_eval.control.closed_loop import run_closed_loop
from mrnc_eval.control.scenario import scripted_scenario
from mrnc_eval.data import ImuSeries, Trajectory, Twists, Waypoints
from mrnc_eval.io.geodesy import enu_to_lla
from mrnc_eval.io.trajectory_files import write_tum
from mrnc_eval.io.writers import LogWriter
from mrnc_eval.sim.lidar import LidarSimulator
from mrnc_eval.sim.motion import BodyMotion
from mrnc_eval.sim.scene import build_scene

LOG_EPOCH_S = 1_763_800_000.0  # start of every simulated log (sensor clock), s
LIDAR_MODELS = {"os0-128": 128, "os0-64": 64, "os0-32": 32}


@dataclass(frozen=True)
class SimRequest:
    scene: str = "yard"
    path: str = "circle"
    duration_s: float | None = None
    lidar: str = "os0-128"
    columns: int = 1024
    rate_hz: float = 10.0
    fmt: str = "mcap"
    seed: int = 0


def transform(xyz, rot=None) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = xyz
    if rot is not None:
        t[:3, :3] = rot
    return t


def simulate_log(out: Path, cfg: Config, req: SimRequest,
                 progress: Callable[[int, int], None] | None = None) -> Path:
    """Write the log to `out` (atomically) and the ground truth TUM beside it; returns the log path."""
    if req.lidar not in LIDAR_MODELS:
        raise ValueError(f"unknown LiDAR {req.lidar!r}; choose from {', '.join(LIDAR_MODELS)}")
    if req.columns not in (512, 1024, 2048) or req.rate_hz not in (10.0, 20.0):
        raise ValueError("OS0 runs 512/1024/2048 columns at 10 or 20 Hz")
    scfg = cfg.sim
    lcfg = replace(scfg.lidar, beams=LIDAR_MODELS[req.lidar], columns=req.columns, rate_hz=req.rate_hz)
    rng = np.random.default_rng(req.seed)

    scenario = scripted_scenario(req.path, cfg.control, size_m=scfg.path_size_m)
    trace = run_closed_loop(scenario, cfg.control, cfg.robot, "raid", duration_s=req.duration_s, seed=req.seed)
    terrain_centre = scenario.waypoints_xy.mean(axis=0)
    scene = build_scene(req.scene, seed=req.seed, amplitude_m=scfg.terrain_amplitude_m,
                        roughness_m=scfg.terrain_roughness_m, centre=tuple(terrain_centre))
    motion = BodyMotion(trace.t, trace.x, trace.y, np.unwrap(trace.yaw), scene.terrain)
    t_end = float(trace.t[-1]) if req.duration_s is None else float(req.duration_s)
    base_to_sensor = transform(lcfg.mount_xyz_m)
    sensor_to_imu = transform(scfg.imu.mount_xyz_m)
    base_to_imu = base_to_sensor @ sensor_to_imu
    base_to_gnss = transform(scfg.gnss.antenna_xyz_m)
    base_to_chassis = transform((0.0, 0.0, 0.3))

    def stamps(rate: float) -> np.ndarray:
        return np.arange(0.0, t_end, 1.0 / rate)

    writer = LogWriter(out, req.fmt)
    try:
        t0 = LOG_EPOCH_S
        writer.write_tf_static([("base_link", "os_sensor", base_to_sensor),
                                ("os_sensor", "os_lidar", transform((0, 0, 0.03618), Rotation.from_euler("z", math.pi).as_matrix())),
                                ("os_sensor", "os_imu", sensor_to_imu), ("base_link", "chassis_imu", base_to_chassis),
                                ("base_link", "gnss", base_to_gnss)], t0)
        writer.write_path("/plan", Waypoints(scenario.waypoints_xy, frame_id="map"), t0)
        _write_imu(writer, "/ouster/imu", "os_imu", motion, stamps(scfg.imu.rate_hz), base_to_imu, scfg.imu, rng, t0)
        if scfg.imu.chassis_rate_hz > 0:
            _write_imu(writer, "/chassis/imu", "chassis_imu", motion, stamps(scfg.imu.chassis_rate_hz),
                       base_to_chassis, scfg.imu, rng, t0)
        _write_gnss(writer, motion, stamps(scfg.gnss.rate_hz), base_to_gnss, scfg.gnss, rng, t0)
        gt = _write_wheels_and_truth(writer, trace, motion, stamps(scfg.wheel_rate_hz),
                                     stamps(scfg.ground_truth_rate_hz), cfg, t0)
        lidar = LidarSimulator(scene, lcfg, base_to_sensor, rng)
        sweep_times = np.arange(0.0, t_end - 1.0 / lcfg.rate_hz, 1.0 / lcfg.rate_hz)
        kept = [k for k in range(sweep_times.size) if k % lcfg.record_every == 0]
        for n, k in enumerate(kept):
            s = lidar.sweep(motion, float(sweep_times[k]))
            writer.write_ouster_cloud("/ouster/points", t0 + s.stamp, s.xyz, s.t_ns, s.range_mm, s.reflectivity,
                                      s.intensity, s.ambient)
            if progress is not None:
                progress(n + 1, len(kept))
        path = writer.close()
    except BaseException:
        writer.abort()
        raise
    write_tum(gt_tum_path(path), gt)
    return path


def gt_tum_path(log_path: Path) -> Path:
    name = log_path.name
    for suffix in (".mcap", ".db3", ".bag"):
        name = name.removesuffix(suffix)
    return log_path.with_name(name + ".gt.tum")


def _write_imu(writer, topic, frame, motion, times, base_to_imu, icfg, rng, t0) -> None:
    f, w, _, _ = motion.imu_kinematics(times, base_to_imu[:3, 3])
    r_bi = base_to_imu[:3, :3]
    f, w = f @ r_bi, w @ r_bi  # body -> IMU axes (identity for the Ouster mount)
    rate = 1.0 / np.median(np.diff(times)) if times.size > 1 else 100.0
    n = times.size
    acc_bias = np.cumsum(rng.normal(0, icfg.acc_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    gyro_bias = np.cumsum(rng.normal(0, icfg.gyro_bias_walk / math.sqrt(rate), (n, 3)), axis=0)
    acc = f + acc_bias + rng.normal(0, icfg.acc_noise_density * math.sqrt(rate), (n, 3))
    gyro = w + gyro_bias + rng.normal(0, icfg.gyro_noise_density * math.sqrt(rate), (n, 3))
    writer.write_imu(topic, ImuSeries(times + t0, acc, gyro, None, frame),
                     acc_var=(icfg.acc_noise_density ** 2) * rate, gyro_var=(icfg.gyro_noise_density ** 2) * rate)


def _write_gnss(writer, motion, times, base_to_gnss, gcfg, rng, t0) -> None:
    p, r = motion.pose(times)
    enu = p + r.apply(base_to_gnss[:3, 3])
    noise = rng.normal(0, 1, enu.shape) * [gcfg.sigma_horizontal_m, gcfg.sigma_horizontal_m, gcfg.sigma_vertical_m]
    enu = enu + noise
    if gcfg.multipath_jump_m > 0:
        a, b = gcfg.multipath_interval_s
        enu[(times >= a) & (times < b), 0] += gcfg.multipath_jump_m
    status = np.where(rng.random(times.size) < gcfg.dropout_probability, -1, 0)
    cov = np.tile(np.diag([gcfg.sigma_horizontal_m ** 2, gcfg.sigma_horizontal_m ** 2, gcfg.sigma_vertical_m ** 2]),
                  (times.size, 1, 1))
    lla = enu_to_lla(enu, np.asarray(gcfg.origin_lla, float))
    writer.write_navsatfix("/gnss/fix", times + t0, lla, cov, status)


def _write_wheels_and_truth(writer, trace, motion, wheel_t, gt_t, cfg: Config, t0) -> Trajectory:
    r = cfg.robot.wheel_radius_m
    interp = lambda a: np.interp(wheel_t, trace.t, a)  # noqa: E731
    vl, vr = interp(trace.v_wheel_left), interp(trace.v_wheel_right)
    writer.write_joint_state("/wheel_speeds", wheel_t + t0, ["left_wheel", "right_wheel"], np.c_[vl / r, vr / r])
    writer.write_joint_state("/pump_cmd", wheel_t + t0, ["left_pump", "right_pump"],
                             np.c_[interp(trace.u_left), interp(trace.u_right)])
    writer.write_twist_stamped("/cmd_vel", Twists(wheel_t + t0, interp(trace.cmd_v), interp(trace.cmd_omega)))
    # wheel odometry: integrate the measured wheel speeds (drifts where the wheels slip)
    dt = np.diff(wheel_t, prepend=wheel_t[0])
    v, w = 0.5 * (vl + vr), (vr - vl) / cfg.robot.track_width_m
    yaw = trace.yaw[0] + np.cumsum(w * dt)
    x = trace.x[0] + np.cumsum(v * np.cos(yaw) * dt)
    y = trace.y[0] + np.cumsum(v * np.sin(yaw) * dt)
    q = Rotation.from_euler("z", yaw[:, None]).as_quat()
    writer.write_odometry("/wheel_odom", Trajectory(wheel_t + t0, np.c_[x, y, np.zeros_like(x)], q), "odom", "base_link",
                          linear_velocity=np.c_[v, 0 * v, 0 * v], angular_velocity=np.c_[0 * w, 0 * w, w])
    p, rot = motion.pose(gt_t)
    gt = Trajectory(gt_t + t0, p, rot.as_quat(), name="ground_truth", frame_id="map", child_frame_id="base_link")
    writer.write_odometry("/ground_truth", gt, "map", "base_link")
    return gt
