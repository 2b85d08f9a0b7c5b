"""`info`'s cross-checks of a log's sensors before any run, with the same rules the SLAM applies:
the accelerometer's unit (slam/imu_units.py), the IMU's axes against the machine's turns
(slam/imu_axes.py), and the wheel odometry's pose and clock against the gyro (commands/slam_wheels.py,
slam/wheel_clock.py). Each finding is (level, topic, message)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from mrnc_eval.config import Config
from mrnc_eval.data import ImuSeries

if TYPE_CHECKING:
    from mrnc_eval.io.reader import LogReader

Found = tuple[str, str, str]  # level ("ok", "warning", "error"), topic, message


def imu_in_si(imu: ImuSeries, topic: str, cfg: Config) -> tuple[ImuSeries, list[Found]]:
    """The IMU with its accelerometer in m/s^2 (a driver writing g scaled), and what was found: a
    warning when scaled, an error when the specific force is in neither unit (slam's lio refuses it)."""
    from mrnc_eval.slam.imu_units import accelerometer_scale

    scale, median = accelerometer_scale(imu.acc, cfg.slam.imu.gravity)
    if scale == 1.0:
        return imu, []
    if scale is None:
        return imu, [("error", topic, f"the accelerometer's median |specific force| is {median:.3g}, neither "
                      f"gravity's {cfg.slam.imu.gravity:g} m/s^2 nor 1 g: not an accelerometer in m/s^2 or g")]
    return dataclasses.replace(imu, acc=imu.acc * scale), [
        ("warning", topic, f"the accelerometer reads in g (median |specific force| {median:.3f}), not m/s^2 as "
         f"sensor_msgs/Imu requires: scaled by {scale:g}")]


def imu_and_wheel_findings(lg: LogReader, imu: ImuSeries, cfg: Config) -> list[Found]:
    """The IMU's axes against the turns, and the wheel odometry's pose and clock against the gyro,
    through /tf_static's base_link -> IMU transform (nothing without one)."""
    from mrnc_eval.commands.slam_wheels import clock_checked, read_wheel_track
    from mrnc_eval.slam.imu_axes import imu_axes

    frames = {f for pair in lg.static_transforms() for f in pair}
    if not imu.frame_id or not {"base_link", imu.frame_id} <= frames:
        return []
    imu_in_base = lg.transform("base_link", imu.frame_id)
    topic = lg.roles["imu"]
    found: list[Found] = []
    axes = imu_axes(imu.stamps, imu.gyro @ imu_in_base[:3, :3].T, cfg.slam.imu_axes)
    if axes.verdict == "rotated":
        found.append(("warning", topic, f"the IMU's axes look rotated in /tf_static: {axes.reasons[0]}"))
    elif axes.verdict == "ok":
        found.append(("ok", topic, f"the machine turns about base_link z in the IMU's axes (within "
                      f"{axes.angle_deg:.0f} deg, over {axes.turned_rad:.1f} rad of turns)"))
    track, note = read_wheel_track(lg, cfg.slam)
    wheel_topic = lg.roles.get("wheel_odom", "")
    if note:
        found.append(("warning", wheel_topic, note))
    _, clock = clock_checked(track, imu, imu_in_base, cfg.slam)
    if clock is not None and clock.verdict in ("late", "early"):
        found.append(("warning", wheel_topic, f"wheel odometry stamped {abs(clock.offset_s) * 1e3:.0f} +- "
                      f"{clock.sigma_s * 1e3:.0f} ms {clock.verdict} against the IMU (from the log's turns): slam "
                      f"takes it out; slam.wheel_odom.time_offset_s={clock.offset_s:.3f} says it for this machine"))
    elif clock is not None and clock.verdict == "ok":
        found.append(("ok", wheel_topic, f"wheel odometry on the IMU's clock ({clock.offset_s * 1e3:+.0f} +- "
                      f"{clock.sigma_s * 1e3:.0f} ms)"))
    return found

