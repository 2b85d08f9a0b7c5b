"""Simulator parameters: sensors, noise densities (with units), mounting, GNSS origin."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from mrnc_eval.params import param, section


@dataclass(frozen=True)
class LidarSimConfig:
    """The simulated LiDAR (Ouster OS0 class)."""

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
    cloud_layout: Literal["organised", "returns"] = param(
        "organised", "organised: ouster-ros' original point type for every pixel (48 B a point, no-return pixels "
        "as zeros); returns: the returns only, x y z intensity (f32), t (u32 ns), ring (u16) in 24 B, as a "
        "recording node that slims the driver's cloud to what a deskewing SLAM reads writes it")
    xyz_step_m: float = param(0.0, "stored coordinates are rounded to multiples of this (0 = as computed); "
                              "0.0078125 (2^-7 m) is the low-bandwidth profile's 8 mm range step and zeroes the "
                              "float's low bits so the bag's compression works", "m")
    full_rate_window_s: tuple[float, float] | None = param(None, "record every sweep that starts in [start, end) "
                                                           "of log time, every record_every-th outside it (a "
                                                           "full-rate stretch for peer comparisons)", "s")


@dataclass(frozen=True)
class ImuSimConfig:
    """The simulated IMU."""

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
    """The simulated GNSS receiver."""

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
    mode: Literal["profile", "rtk", "float", "single"] = param(
        "profile", "fix type: profile (ideal: the noise above; field: from the distance to structures, "
        "sim.field.gnss), or the same type all the time: rtk (fixed, sim.field.gnss.sigma_fixed_m), float "
        "(sigma_float_m with multipath jumps everywhere at multipath_rate_hz), single (sigma_single_m)")
    outages_s: tuple[tuple[float, float], ...] = param((), "intervals [start, end) since the log start without "
                                                       "any fix (NO_FIX: under trees, a bridge, a shed)", "s")


@dataclass(frozen=True)
class WheelSimConfig:
    """Wheel-odometry errors of a real skid-steer, separate from the plant: the plant drives the
    true speeds, the odometry topic and the wheel speeds carry these. Defaults: a calibrated
    machine (scale and left/right radii good to 0.5 %, skid 1.1x, hydraulic speed pickups)."""

    model: Literal["profile", "exact", "errors"] = param(
        "profile", "exact: the plant's wheel speeds (slip only); errors: the errors below; profile: errors with "
        "sim.profile = field, exact with ideal")
    scale_error: float = param(0.005, "common speed scale error, |fraction| (effective rolling radius); the sign "
                               "is drawn per log", ge=0.0, lt=1.0)
    lr_mismatch: float = param(0.005, "left/right radius mismatch, |fraction| (right x (1 + m/2), left x "
                               "(1 - m/2)); the sign is drawn per log", ge=0.0, lt=1.0)
    track_factor: float = param(1.1, "skid in turns: the odometry's yaw = this x the true yaw (effective track "
                                "1.2-2x the geometric one on a real skid-steer; 1 = none)", gt=0.0)
    speed_noise_mps: float = param(0.05, "1-sigma white noise of each side's speed per sample (hydraulic motor "
                                   "speed pickups)", "m/s", ge=0.0)
    yaw_rate_bias_rad_s: float = param(0.0, "|yaw-rate bias| of the odometry; the sign is drawn per log", "rad/s",
                                       ge=0.0)
    random_signs: bool = param(True, "draw the signs of scale, mismatch and bias per log (false: as given)")


@dataclass(frozen=True)
class FieldImuConfig:
    """IMU errors of a consumer MEMS part on a diesel-hydraulic machine (ICM-20948 class, the
    Ouster's internal IMU). Sources per parameter; docs/simulation.md has the table."""

    acc_noise_density: float = param(2.3e-3, "accelerometer white noise (ICM-20948 datasheet: 230 ug/sqrt(Hz))",
                                     "m/s^2/sqrt(Hz)")
    gyro_noise_density: float = param(2.6e-4, "gyro white noise (ICM-20948 datasheet: 0.015 dps/sqrt(Hz))",
                                      "rad/s/sqrt(Hz)")
    acc_bias_walk: float = param(1e-4, "accelerometer bias random walk (not in the datasheet; order of published "
                                 "Allan deviations of MPU-9250/ICM-20948-class parts)", "m/s^3/sqrt(Hz)")
    gyro_bias_walk: float = param(1e-5, "gyro bias random walk (as above)", "rad/s^2/sqrt(Hz)")
    acc_turn_on_bias: float = param(0.1, "1-sigma turn-on bias per accelerometer axis (datasheet board-level "
                                    "zero-g offset bound +-50 mg = 0.49 m/s^2; sigma = a fifth of it)", "m/s^2")
    gyro_turn_on_bias: float = param(0.01, "1-sigma turn-on bias per gyro axis (datasheet bound +-5 dps; the "
                                     "real Ouster recording's 0.3 s gyro means are 0.005, 0.016, 0.00003 rad/s)",
                                     "rad/s")
    vibration_hz: tuple[float, ...] = param((30.0, 60.0), "engine vibration lines: crankshaft and firing "
                                            "frequency of a 4-cylinder 4-stroke diesel at 1800 rpm (30 and 60 Hz; "
                                            "sampled at 100 Hz without anti-aliasing, 60 Hz folds to 40 Hz)", "Hz")
    vibration_acc_rms: float = param(0.5, "vibration RMS per accelerometer axis, over all lines (order of the "
                                     "whole-body vibration of earth-moving machines; EU 2002/44/EC action value "
                                     "0.5 m/s^2; the handled real recording shows 0.4-0.8 m/s^2 std)", "m/s^2")
    vibration_gyro_rms: float = param(0.01, "vibration RMS per gyro axis (assumed: a rigid mast rocking "
                                      "+-0.5 mrad at tens of Hz)", "rad/s")
    acc_range: float = param(19.6133, "accelerometer saturation (ICM-20948 smallest full scale +-2 g; the Ouster's "
                             "setting is not documented)", "m/s^2")
    gyro_range: float = param(4.3633, "gyro saturation (ICM-20948 smallest full scale +-250 dps)", "rad/s")
    acc_lsb: float = param(5.9855e-4, "accelerometer quantisation (16 bit over +-2 g)", "m/s^2")
    gyro_lsb: float = param(1.3323e-4, "gyro quantisation (16 bit over +-250 dps)", "rad/s")
    drop_probability: float = param(0.002, "probability that a 100 Hz sample is missing (driver or UDP loss; "
                                    "assumed)")


@dataclass(frozen=True)
class FieldClockConfig:
    """Stamps as the drivers write them. Convention: header stamp = true time + offset + jitter."""

    imu_offset_s: float = param(0.005, "constant IMU-vs-LiDAR stamp offset: IMU header stamps are this much later "
                                "than the true sample time, LiDAR stamps are not (a few ms, e.g. an IMU stamped "
                                "on arrival at the host)", "s")
    imu_jitter_s: float = param(2e-7, "1-sigma jitter of IMU stamps (measured: std of the 100 Hz stamp steps of "
                                "the real Ouster recording, 0.2 us)", "s")
    lidar_jitter_s: float = param(3e-5, "1-sigma jitter of sweep stamps (measured: the real recording's sweep "
                                  "steps differ from 0.1 s by 30-50 us)", "s")
    host_jitter_s: float = param(5e-4, "1-sigma jitter of host-stamped topics: wheels, commands, odometry, GNSS "
                                 "(assumed: a non-realtime ROS host)", "s")
    gnss_latency_s: float = param(0.12, "GNSS fixes are stamped this late (serial NMEA/UBX reception after the "
                                  "measurement epoch; assumed, 0.05-0.2 s is typical)", "s")
    wheel_latency_s: float = param(0.0, "the wheel odometry and wheel speeds are stamped this late (a host or PLC "
                                   "bridge; 0: on time, as in every log made before)", "s", ge=0.0, le=1.0)


@dataclass(frozen=True)
class FieldCalibrationConfig:
    """The written /tf_static base_link -> os_sensor is the nominal mount; the true mount that
    the rays and the IMU use is that times this error (fixed, so tests can check it)."""

    lidar_xyz_error_m: tuple[float, float, float] = param((0.03, -0.02, 0.015), "true minus written "
                                                          "base_link -> os_sensor translation (tape-measured "
                                                          "mount: centimetres)", "m")
    lidar_rpy_error_deg: tuple[float, float, float] = param((0.3, -0.4, 0.5), "true relative to written "
                                                            "rotation (roll, pitch, yaw, fixed axes; a fraction "
                                                            "of a degree)", "deg")


@dataclass(frozen=True)
class FieldLidarConfig:
    """The field profile's LiDAR: body returns, range noise, beam divergence, mixed pixels, dark and wet surfaces."""

    body_in_cloud: bool = param(True, "the machine's body returns rays (sim.lidar.self_occlusion on)")
    range_noise_floor_m: float = param(0.01, "1-sigma range noise of a bright target up close (OS0 datasheet "
                                       "precision class, +-1 cm)", "m")
    range_noise_ref_m: float = param(0.03, "... grows to this at the reference range on a 10 % target "
                                     "(OS0 datasheet precision class, +-3 cm at long range); sigma = floor (+) "
                                     "ref * (r / ref_range) * sqrt(0.1 / reflectivity), i.e. 1 / sqrt(SNR)", "m")
    range_noise_ref_range_m: float = param(35.0, "reference range of range_noise_ref_m (the detection range of "
                                           "a 10 % target, sim.lidar.detect_range_10pct_m)", "m")
    beam_divergence_deg: float = param(0.35, "full beam divergence (OS0 datasheet class, 0.35 deg FWHM): spreads "
                                       "the range on inclined surfaces and makes mixed pixels at depth edges", "deg")
    mixed_pixel_jump_m: float = param(0.3, "a depth edge: neighbouring columns differ by more than this", "m")
    outlier_fraction: float = param(0.01, "fraction of returns with a random range between the minimum range "
                                    "and the true one (dust, rain, multiple echoes; the issue's ~1 %)")
    dark_albedo: float = param(0.08, "returns from surfaces darker than this (albedo x cos incidence) drop "
                               "with probability 1 - value / dark_albedo (assumed)")
    wet_patches_per_100m2: float = param(0.5, "wet patches (puddles) on the ground, per 100 m^2 (assumed)")
    wet_patch_radius_m: tuple[float, float] = param((0.5, 2.0), "puddle radius range", "m")
    wet_albedo: float = param(0.03, "NIR albedo of wet ground (water absorbs 865 nm; mostly no return)")


@dataclass(frozen=True)
class FieldWorldConfig:
    """The field profile's world: terrain roughness, stones, shaking, a moving object."""

    terrain_roughness_m: float = param(0.04, "small-scale roughness amplitude (wavelengths 2.7-3.7 m; the "
                                       "ideal profile uses sim.terrain_roughness_m)", "m")
    stones_per_m: float = param(0.5, "stones and ruts a wheel rolls over, per metre driven (assumed, rough "
                                "site ground)", "1/m")
    stone_height_m: tuple[float, float] = param((0.02, 0.06), "height range of a stone under one wheel", "m")
    stone_length_m: float = param(0.3, "travel over which a wheel climbs and leaves a stone (tyre contact "
                                  "patch of a large tyre; assumed)", "m")
    wheelbase_m: float = param(2.0, "distance between the front and rear axles, for the pitch a stone causes "
                               "(assumed: half the 4 m body length)", "m")
    shake_hz: float = param(2.5, "body bounce/pitch natural frequency on its tyres (heavy wheeled machines "
                            "without suspension: 2-3 Hz)", "Hz")
    shake_damping: float = param(0.15, "damping ratio of that mode (tyres: 0.1-0.2)")
    moving_object: Literal["vehicle", "person", "none"] = param("vehicle", "an object crossing the scene "
                                                                "back and forth along a straight line")
    moving_speed_mps: float = param(2.0, "its speed (vehicle 2 m/s in a yard; a walking person: 1.4)", "m/s")
    moving_clearance_m: float = param(3.0, "it never comes closer than this to the machine (horizontal, "
                                      "centre to centre beyond the machine's half-length)", "m")


@dataclass(frozen=True)
class FieldGnssConfig:
    """The field profile's GNSS: fix quality near structures, multipath jumps."""

    sigma_fixed_m: float = param(0.02, "horizontal 1-sigma with an RTK fixed solution in the open (status "
                                 "GBAS_FIX = 2; RTK receivers: 1-2 cm)", "m")
    sigma_float_m: float = param(0.3, "... RTK float / SBAS near structures (status SBAS_FIX = 1)", "m")
    sigma_single_m: float = param(1.5, "... single point close to structures (status FIX = 0)", "m")
    float_within_m: float = param(12.0, "antenna within this of a structure: float", "m")
    single_within_m: float = param(5.0, "... within this: single point", "m")
    multipath_rate_hz: float = param(0.1, "rate of multipath jumps while within float_within_m", "1/s")
    multipath_jump_m: tuple[float, float] = param((0.5, 3.0), "size range of a jump (horizontal)", "m")
    multipath_duration_s: tuple[float, float] = param((2.0, 8.0), "how long a jump lasts", "s")


@dataclass(frozen=True)
class FieldConfig:
    """Used only with sim.profile = field."""

    imu: FieldImuConfig = section(FieldImuConfig, "IMU errors (replace sim.imu's noise densities)")
    clock: FieldClockConfig = section(FieldClockConfig, "stamp offsets, jitter and latency")
    calibration: FieldCalibrationConfig = section(FieldCalibrationConfig, "/tf_static vs the true mount")
    lidar: FieldLidarConfig = section(FieldLidarConfig, "LiDAR return model")
    world: FieldWorldConfig = section(FieldWorldConfig, "rough ground, stones, a moving object")
    gnss: FieldGnssConfig = section(FieldGnssConfig, "fix types and multipath near structures")


@dataclass(frozen=True)
class SimConfig:
    """The synthetic log generator."""

    profile: Literal["ideal", "field"] = param("ideal", "sensor profile: ideal (the logs of before: no biases, "
                                               "one clock, exact mounting, thin rays, static scenes) or field "
                                               "(sim.field.*: what a real machine records)")
    seed: int = param(0, "random seed when the request gives none (--seed wins); the same seed gives "
                          "byte-identical logs")
    bag_compression: Literal["lz4", "bz2", "none"] = param("lz4", "ROS 1 bag chunk compression (rosbag record "
                                                           "--lz4 / --bz2)")
    lidar: LidarSimConfig = section(LidarSimConfig, "Ouster OS0 model")
    imu: ImuSimConfig = section(ImuSimConfig, "IMU model")
    gnss: GnssSimConfig = section(GnssSimConfig, "GNSS model")
    wheels: WheelSimConfig = section(WheelSimConfig, "wheel-odometry errors (scale, left/right, skid, noise)")
    path_size_m: float = param(10.0, "size of the scripted paths (figure8, loop, line); the circle is the paper's", "m")
    scene_scale: float = param(1.0, "stretch the scene for larger paths: distances x this, object counts x its square "
                               "(1: objects within ~40 m of the path's centre, enough for paths up to ~20 m)")
    wheel_rate_hz: float = param(50.0, "wheel speed, pump command, cmd_vel and wheel odometry rate", "Hz")
    ground_truth_rate_hz: float = param(100.0, "ground-truth odometry rate", "Hz")
    terrain_amplitude_m: float = param(0.3, "gentle relief amplitude", "m")
    terrain_roughness_m: float = param(0.02, "small-scale roughness amplitude", "m")
    motion_smoothing_s: float = param(0.1, "the driven trace is smoothed over this time (triangle kernel) before "
                                      "it becomes the ground truth: a 4.8 t machine cannot change speed or yaw rate "
                                      "within one 1 ms control step (0 = as simulated)", "s")
    standstill_s: float = param(0.0, "the machine stands (engine running, sensors recording) this long before it "
                                "sets off, within the requested duration; the IMU's noise and biases can be measured "
                                "from it (0 = drive from the first sample)", "s", ge=0.0, le=3600.0)
    field: FieldConfig = section(FieldConfig, "field profile (sim.profile = field)")
