"""Log-reading configuration: topic role overrides and the GNSS local frame."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.errors import ConfigError
from mrnc_eval.io.roles import ROLES
from mrnc_eval.io.validate import ValidationConfig
from mrnc_eval.params import param, section
from mrnc_eval.spelling import did_you_mean


@dataclass(frozen=True)
class IoConfig:
    """Log reading: topic roles, GNSS origin and unknown variance, the small-topic cache, validation."""

    roles: dict[str, str] = param(
        {},
        "role -> topic overrides (roles: lidar, imu, chassis_imu, gnss, wheel_odom, wheel_speeds, "
        "commands, cmd_vel, path, ground_truth, tf, tf_static, metadata); unset roles are detected by "
        "message type",
    )
    gnss_origin_lla: tuple[float, float, float] | None = param(
        None,
        "geodetic origin (lat deg, lon deg, alt m) of the local ENU frame; "
        "default: the first valid fix of the log",
    )
    gnss_unknown_variance_m2: tuple[float, float, float] = param(
        (4.0, 4.0, 16.0),
        "east/north/up position variance given to fixes whose NavSatFix covariance is unknown "
        "(position_covariance_type 0 or an all-zero diagonal), so no fix is trusted as exact",
        "m^2",
    )
    small_topic_cache_mb: float = param(
        1024.0,
        "the overview pass keeps the raw messages of every topic except clouds and images in memory, "
        "up to this many MB, so IMU, GNSS, odometry and TF are not read from the file again "
        "(a compressed log is decompressed once for them instead of once per series); 0 = off",
        "MB", ge=0.0,
    )
    validation: ValidationConfig = section(ValidationConfig, "stream validation at the reader boundary")

    def __post_init__(self) -> None:
        for role in self.roles:  # a mistyped role would otherwise be ignored and detection used silently
            if role not in ROLES:
                hint = did_you_mean(role, ROLES)
                raise ConfigError(f"io.roles.{role}: unknown role{hint}; roles: {', '.join(ROLES)}")
