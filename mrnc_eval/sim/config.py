"""Simulator parameters: sensors, noise densities (with units), mounting, GNSS origin."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from mrnc_eval.params import param, section


@dataclass(frozen=True)
class LidarSimConfig:
    beams: int = param(128, "beams (OS0: 128, 64 or 32)")
    columns: int = param(1024, "columns per sweep (512, 1024, 2048)")
    rate_hz: float = param(10.0, "sweep rate (10 or 20)", "Hz")
    vertical_fov_deg: float = param(90.0, "vertical field of view, symmetric (OS0: 90)", "deg")
    max_range_m: float = param(50.0, "maximum range; farther returns are no-return zeros", "m")
    min_range_m: float = param(0.3, "minimum range", "m")
    range_noise_m: float = param(0.01, "range noise (1 sigma); ranges are then quantised to the packet "
                                 "profile's step", "m")
    detect_range_10pct_m: float = param(35.0, "range at which a 10 % Lambertian target at normal incidence is "
                                        "still detected (OS0 datasheet class); weaker returns are no-return zeros", "m")
    beam_azimuth_offsets_deg: tuple[float, ...] = param(
        (4.2, 1.4, -1.4, -4.2), "per-ring azimuth offsets, cycled over the rings (staggered columns as ouster-ros "
        "publishes them; the pattern of the shared OS1-128 metadata, 0 = no stagger)", "deg")
    packet_profile: Literal["RNG19_RFL8_SIG16_NIR16", "RNG15_RFL8_NIR8"] = param(
        "RNG19_RFL8_SIG16_NIR16", "Ouster UDP profile: full (1 mm range, photon signal as intensity) or low "
        "bandwidth like the shared real recording (8 mm range steps, intensity = reflectivity, ambient in steps of 16)")
    lidar_origin_to_beam_origin_mm: float = param(27.67, "beam origin offset from the lidar axis (OS0)", "mm")
    lidar_to_sensor_z_m: float = param(0.03618, "os_sensor -> os_lidar height (ouster-ros tf; lidar rotated "
                                       "180 deg about z)", "m")
    sun_elevation_deg: float = param(35.0, "sun elevation for the ambient (NIR) channel", "deg")
    ambient_sunlit_photons: float = param(300.0, "ambient (NIR) count of a white surface facing the sun "
                                          "(overcast daylight; Poisson noise)", "photons")
    ambient_sky_photons: float = param(200.0, "ambient count of a no-return pixel looking at the sky", "photons")
    mount_xyz_m: tuple[float, float, float] = param((1.2, 0.0, 1.9), "base_link -> os_sensor translation", "m")
    self_occlusion: bool = param(False, "the robot's own body (robot.length/width/height, from the ground "
                                 "clearance up) blocks and returns rays, as on the real machine; clouds then "
                                 "need a body crop")
    body_clearance_m: float = param(0.3, "ground clearance of the body box (self_occlusion)", "m")
    record_every: int = param(1, "record every n-th sweep (a throttled recording, like topic_tools throttle)")


@dataclass(frozen=True)
class ImuSimConfig:
    rate_hz: float = param(100.0, "sensor IMU rate (Ouster internal IMU)", "Hz")
    acc_noise_density: float = param(2.3e-3, "accelerometer white noise (ICM-20948 class)", "m/s^2/sqrt(Hz)")
    gyro_noise_density: float = param(2.6e-4, "gyro white noise", "rad/s/sqrt(Hz)")
    acc_bias_walk: float = param(1e-4, "accelerometer bias random walk", "m/s^3/sqrt(Hz)")
    gyro_bias_walk: float = param(1e-5, "gyro bias random walk", "rad/s^2/sqrt(Hz)")
    chassis_rate_hz: float = param(0.0, "chassis IMU rate (ADIS16475: 1000); 0 = no chassis IMU", "Hz")
    chassis_mount_xyz_m: tuple[float, float, float] = param((0.0, 0.0, 0.3), "base_link -> chassis_imu", "m")
    chassis_mount_rpy_deg: tuple[float, float, float] = param((0.0, 0.0, 0.0), "base_link -> chassis_imu rotation "
                                                              "(roll, pitch, yaw; fixed axes x-y-z)", "deg")
    mount_xyz_m: tuple[float, float, float] = param((0.006253, -0.011775, 0.007645),
                                                    "os_sensor -> os_imu translation (Ouster)", "m")


@dataclass(frozen=True)
class GnssSimConfig:
    rate_hz: float = param(5.0, "fix rate", "Hz")
    origin_lla: tuple[float, float, float] = param((61.4498, 23.8595, 120.0), "geodetic origin of the map frame "
                                                   "(lat deg, lon deg, alt m)")
    sigma_horizontal_m: float = param(0.03, "horizontal noise (RTK float class)", "m")
    sigma_vertical_m: float = param(0.05, "vertical noise", "m")
    dropout_probability: float = param(0.02, "probability that a fix is NO_FIX")
    multipath_jump_m: float = param(0.0, "size of a multipath jump (0 = off)", "m")
    multipath_interval_s: tuple[float, float] = param((20.0, 25.0), "when the multipath jump is present "
                                                      "(since the log start)", "s")
    antenna_xyz_m: tuple[float, float, float] = param((0.0, 0.0, 2.2), "base_link -> gnss antenna", "m")


@dataclass(frozen=True)
class SimConfig:
    seed: int = param(0, "random seed when the request gives none (--seed wins); the same seed gives "
                          "byte-identical logs")
    bag_compression: Literal["lz4", "bz2", "none"] = param("lz4", "ROS 1 bag chunk compression (rosbag record "
                                                           "--lz4 / --bz2)")
    lidar: LidarSimConfig = section(LidarSimConfig, "Ouster OS0 model")
    imu: ImuSimConfig = section(ImuSimConfig, "IMU model")
    gnss: GnssSimConfig = section(GnssSimConfig, "GNSS model")
    path_size_m: float = param(10.0, "size of the scripted paths (figure8, loop, line); the circle is the paper's", "m")
    scene_scale: float = param(1.0, "stretch the scene for larger paths: distances x this, object counts x its square "
                               "(1: objects within ~40 m of the path's centre, enough for paths up to ~20 m)")
    wheel_rate_hz: float = param(50.0, "wheel speed, pump command, cmd_vel and wheel odometry rate", "Hz")
    ground_truth_rate_hz: float = param(100.0, "ground-truth odometry rate", "Hz")
    terrain_amplitude_m: float = param(0.3, "gentle relief amplitude", "m")
    terrain_roughness_m: float = param(0.02, "small-scale roughness amplitude", "m")
