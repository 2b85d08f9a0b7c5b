"""The wheel odometry a lio run reads: the log's odom -> base_link track, its stamps less the known
clock lag (slam.wheel_odom.time_offset_s) and, when the clock check (slam/wheel_clock.py) flags an
offset against the gyro, less that too."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from mrnc_eval.data import ImuSeries
from mrnc_eval.slam.wheel_calibration import WheelIncrements, gyro_yaw_rate, track_from_twist
from mrnc_eval.slam.wheel_clock import WheelClock, wheel_clock
from mrnc_eval.slam.wheel_odometry import WheelTrack

if TYPE_CHECKING:
    from mrnc_eval.io.reader import LogReader
    from mrnc_eval.slam.config import SlamConfig


FROZEN_M, FROZEN_RAD = 1e-3, 1e-3  # a pose that moves less than this over the whole log does not move
FROZEN_MOVING = 0.05  # a twist faster than this (m/s or rad/s) does


def read_wheel_track(lg: LogReader, cfg: SlamConfig) -> tuple[WheelTrack | None, str]:
    """The wheel odometry when slam.wheel_odom.enabled, the method is lio and the log has it, its
    stamps less slam.wheel_odom.time_offset_s; and a note when its pose never moves while its twist
    does (a driver that publishes only the twist: read by the pose the machine would stand all log,
    open loop 0.026 -> 4.8 m online APE), where the twist is dead-reckoned instead."""
    if cfg.method != "lio" or not cfg.wheel_odom.enabled or not lg.has_role("wheel_odom"):
        return None, ""
    odom = lg.wheel_odometry()
    track, note = WheelTrack(stamps=odom.stamps, positions=odom.positions, quat_xyzw=odom.quat_xyzw), ""
    if _frozen(track):
        twist = lg.odometry_twist()
        if twist.stamps.size > 2 and max(np.abs(twist.v).max(), np.abs(twist.omega).max()) > FROZEN_MOVING:
            track = track_from_twist(twist.stamps, twist.v, twist.omega)
            note = (f"wheel odometry {lg.roles['wheel_odom']}: its pose never moves while its twist does (up to "
                    f"{np.abs(twist.v).max():.2f} m/s): the SLAM dead-reckoned the twist")
    return dataclasses.replace(track, stamps=track.stamps - cfg.wheel_odom.time_offset_s), note


def _frozen(track: WheelTrack) -> bool:
    """The track's pose stays within FROZEN_M and FROZEN_RAD (yaw) over the whole log."""
    yaw = np.cumsum(WheelIncrements.of(track).yaw_rad) if track.stamps.size > 1 else np.zeros(0)
    return bool(np.ptp(track.positions, axis=0).max() < FROZEN_M and np.abs(yaw).max(initial=0.0) < FROZEN_RAD)


def clock_checked(track: WheelTrack | None, imu: ImuSeries | None, imu_in_base: np.ndarray, cfg: SlamConfig
                  ) -> tuple[WheelTrack | None, WheelClock | None]:
    """The track with a flagged clock offset taken out of its stamps (slam.wheel_odom.clock.apply), and
    the check's record; (track, None) when the check is off or there is no track or IMU."""
    ccfg = cfg.wheel_odom.clock
    if not ccfg.enabled or track is None or imu is None or track.stamps.size < 3:
        return track, None
    inc = WheelIncrements.of(track)
    gt, gw = gyro_yaw_rate(imu, imu_in_base)
    order = np.argsort(gt, kind="stable")  # the reader sorts its streams; a hand-made series may not be
    clock = wheel_clock(inc.stamps, np.r_[0.0, np.cumsum(inc.yaw_rad)], np.r_[0.0, np.cumsum(inc.forward_m)],
                        gt[order] - cfg.imu.time_offset_s, gw[order], ccfg)
    if clock.verdict in ("late", "early") and ccfg.apply:
        clock.applied_s = clock.offset_s
        track = dataclasses.replace(track, stamps=track.stamps - clock.offset_s)
    return track, clock


def clock_warning(clock: WheelClock, known_s: float) -> str | None:
    """The warning for a flagged wheel clock: what was found, whether the run took it out, and the
    setting that says it next time."""
    if clock.verdict not in ("late", "early"):
        return None
    total = known_s + clock.offset_s
    done = ("the run took it out of the wheel stamps" if clock.applied_s
            else "not applied (slam.wheel_odom.clock.apply is false)")
    return (f"wheel odometry stamped {abs(clock.offset_s) * 1e3:.0f} ms {clock.verdict} against the IMU "
            f"(+- {clock.sigma_s * 1e3:.0f} ms, from the log's turns): {done}; set "
            f"slam.wheel_odom.time_offset_s={total:.3f} for this machine")
