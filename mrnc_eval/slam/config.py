"""SLAM parameters. Defaults follow LIO-SAM's params.yaml (shared/docs/lio-sam-reference.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from mrnc_eval.params import param, section


@dataclass(frozen=True)
class SensorConfig:
    """The LiDAR (defaults: Ouster OS0-128 x 1024 at 10 Hz, as on the robot)."""

    lidar_frame: str = param("os_sensor", "frame of the point clouds (Ouster driver: os_sensor)")
    n_scan: int = param(128, "beams (N_SCAN); used only when the cloud carries no ring field")
    horizon_scan: int = param(1024, "columns per sweep (Horizon_SCAN); used when the cloud has no column")
    downsample_rate: int = param(1, "keep every n-th ring (downsampleRate)")
    vertical_fov_deg: tuple[float, float] = param((-45.0, 45.0), "OS0 vertical field of view [min, max], "
                                                   "for rings computed from elevation", "deg")
    mount_rpy_correction_deg: tuple[float, float, float] = param(
        (0.0, 0.0, 0.0), "rotation applied to /tf_static's base_link -> LiDAR mount (right-multiplied: roll, pitch, "
        "yaw about the LiDAR's fixed axes); the mount check (slam.mount_check) tells the value when the motion shows "
        "the mount rotated", "deg", ge=-10.0, le=10.0)


@dataclass(frozen=True)
class ImuConfig:
    """IMU noise model, extrinsics and the preintegration graph (graph #2)."""

    acc_noise: float = param(3.9939570888238808e-03, "accelerometer white noise sigma (imuAccNoise)", "m/s^2",
                             gt=0.0)
    gyro_noise: float = param(1.5636343949698187e-03, "gyroscope white noise sigma (imuGyrNoise)", "rad/s", gt=0.0)
    acc_bias_noise: float = param(6.4356659353532566e-05, "accelerometer bias random walk (imuAccBiasN)", "m/s^3",
                                  gt=0.0)
    gyro_bias_noise: float = param(3.5640318696367613e-05, "gyroscope bias random walk (imuGyrBiasN)", "rad/s^2",
                                   gt=0.0)
    integration_noise: float = param(1e-4, "integration noise sigma of the preintegration", gt=0.0)
    gravity: float = param(9.80511, "gravity magnitude (imuGravity)", "m/s^2")
    rpy_weight: float = param(0.01, "slerp weight pulling the matched roll/pitch towards the IMU's orientation "
                              "(imuRPYWeight); 9-axis IMUs only: a 6-axis IMU has no orientation, the blend is off")
    extrinsic_rot: list[list[float]] | None = param(None, "3x3 rotation taking IMU-frame vectors into the "
                                                    "LiDAR frame (extrinsicRot); None = from /tf_static")
    extrinsic_trans: list[float] | None = param(None, "IMU position in the LiDAR frame (extrinsicTrans); "
                                                "None = from /tf_static", "m")
    attitude_window_s: float = param(0.5, "6-axis IMU: initial roll/pitch from the accelerometer averaged over "
                                     "this long before the first sweep (the machine stands or moves steadily)", "s")
    attitude_lookahead_s: float = param(0.1, "... and this long after it: a machine that starts driving with the log "
                                        "accelerates, and 0.1 m/s^2 of start-up acceleration in the average tilts the "
                                        "map by 0.6 deg, which leaks 0.1 m/s^2 of gravity into the IMU prediction "
                                        "(the 0.5 s window used before drifted 7 m in 40 s of open field)", "s")
    attitude_driving_window_s: float = param(
        2.0, "6-axis IMU, a log begun mid-drive (the wheels' first 0.2 s faster than "
        "wheel_odom.calibration.stationary_speed_mps): initial roll/pitch from the specific force over this long "
        "after the first sweep, rotated to it by the gyro, less the IMU's velocity change (the wheels' plus its "
        "lever's rocking about base_link); the 0.1 s look-ahead reads the ground's bumps (31 deg of roll on the "
        "open line begun at 12 s, seed 4). 0.4 s or less = off", "s",
        ge=0.0, le=10.0)
    use_heading_init: bool = param(False, "start the map yaw at the 9-axis IMU's yaw (useImuHeadingInitialization); "
                                   "6-axis IMUs have no heading")
    use_preintegration_graph: bool = param(True, "estimate velocity and biases with gtsam ImuFactors and lidar pose "
                                           "priors (LIO-SAM imuPreintegration); off = constant-velocity guess")
    pose_prior_sigmas: tuple[float, float, float, float, float, float] = param(
        (0.05, 0.05, 0.05, 0.1, 0.1, 0.1), "lidar pose prior sigmas in graph #2 [rot rad, trans m]")
    degenerate_pose_sigma: float = param(1.0, "... when scan-to-map was degenerate")
    degenerate_prior: Literal["directions", "all"] = param(
        "directions", "degenerate scan-to-map: directions = degenerate_pose_sigma only along the projected-out "
        "directions (the IMU carries them, the rest stays measured); all = on all six (LIO-SAM)")
    reset_every: int = param(100, "restart graph #2 every n keys, keeping its velocity and bias estimates")
    reset_priors: Literal["marginals", "fixed"] = param(
        "fixed", "priors of graph #2's periodic restart: marginals = the pose, velocity and bias marginal covariances "
        "at the last key (LIO-SAM); fixed = pose_prior_sigmas, 1 m/s and bias_prior_sigmas around the estimates "
        "(marginals measured no better: field OS0-32, seeds 0-2, online APE median 0.0167 -> 0.0173 m)")
    noise_from_log: bool = param(True, "preintegration noise densities and the initial gyro bias from the log's "
                                 "stationary stretches (slam/imu_noise.py; reported either way as imu_noise), and "
                                 "acc_turn_on_sigma for the initial accelerometer bias; without a stationary "
                                 "stretch, or off: the noise sigmas above and a zero bias held by bias_prior_sigmas "
                                 "(field OS0-32, seeds 0-2: online APE median 0.0167 -> 0.0150 m, worst 0.0378 -> "
                                 "0.0364 m; docs/simulation.md)")
    bias_prior_sigmas: tuple[float, float] = param((1e-3, 1e-3), "bias prior sigmas [acc m/s^2, gyro rad/s] at "
                                                   "each start of graph #2 (LIO-SAM: 1e-3 on both)")
    acc_turn_on_sigma: float = param(0.1, "with noise_from_log: the initial accelerometer bias prior sigma, the "
                                     "turn-on bias class of the part (a consumer MEMS: 0.1 m/s^2; a stationary "
                                     "stretch cannot tell the horizontal bias from a tilt)", "m/s^2", gt=0.0, le=10.0)
    deskew_motion: Literal["predicted", "last"] = param(
        "last", "translation deskew (slam.deskew_translation): predicted = graph #2's velocity at the sweep's start "
        "and end (constant acceleration over the sweep); last = the velocity of the last mapped sweep, constant")
    stationary_min_s: float = param(1.5, "shortest stationary stretch the IMU noise is measured from", "s",
                                    gt=0.0, le=3600.0)
    standing_start_min_s: float = param(0.3, "without such a stretch, graph #2's initial gyro bias is the gyro's mean "
                                        "over a standing start at least this long (slam/imu_noise.py "
                                        "standing_start_bias: without wheels on bare ground the heading is the "
                                        "gyro's, and the field IMU's turn-on bias turns it by a degree a second); "
                                        "0 = off", "s", ge=0.0, le=3600.0)
    standing_start_max_rate_rad_s: float = param(0.03, "... not when that mean about the vertical exceeds this (a log "
                                                 "begun mid-turn; 1.7 deg/s: consumer MEMS turn-on offsets are 0.5-1 "
                                                 "deg/s, the ICM-20948's board-level bound +-5)", "rad/s", gt=0.0,
                                                 le=10.0)
    restart_after_loop_m: float = param(0.1, "restart graph #2 after a loop closure that moved the current keyframe "
                                        "more than this; smaller corrections are absorbed by its pose prior (a "
                                        "restart in a degenerate stretch costs more than it gains)", "m")
    sample_hold: Literal["centred", "forward"] = param(
        "centred", "how an IMU sample covers time in deskew and preintegration: centred = over the half periods "
        "around its stamp (a point measurement); forward = from its stamp to the next (lags by half a period)")
    time_offset_s: float = param(0.0, "known IMU clock lag: subtracted from every IMU stamp before anything "
                                 "else (positive when the IMU stamps are late)", "s")
    estimate_time_offset: bool = param(True, "estimate the remaining IMU-LiDAR offset after the run "
                                       "(imu_time_offset_s in metrics.json)")
    time_offset_from: Literal["rematch", "online"] = param(
        "rematch", "with estimate_time_offset: the LiDAR rotations the offset is read from. rematch = after the "
        "run, the kept mapped sweeps matched again without any prior from their final poses against the "
        "keyframes more than 5 s from them in time, in their final poses (neither the IMU nor the wheels move "
        "them, nor the keyframes' own lag through the same turn; slam/offset_rematch.py); online = the poses "
        "as the run estimated them (they keep part of the IMU-driven "
        "guess and the wheels' yaw: a lag reads 0.65-1.0 of itself on the field logs)")
    time_offset_rematch_max_sweeps: int = param(
        600, "with time_offset_from=rematch: at most this many mapped sweeps kept for the re-match (their "
        "features, 42 kB each on the field logs' OS0-32 x 512): over it the log's 2 s stretches "
        "are thinned, every other one dropped (a 40 s log mapped at 5 Hz keeps all 200, a 100 s one all 500)",
        ge=20, le=100_000)
    time_offset_rematch_max_points: int = param(
        2000, "with time_offset_from=rematch: at most this many edge and this many surface points of each kept "
        "sweep, every k-th (the field logs' OS0-32 x 512 sweeps: 80-200 edge, 2,300-3,300 surface points; an "
        "OS0-128 x 1024 sweep's 11,600 surface points cost 3x the CPU and memory for the same estimate)",
        ge=100, le=10_000_000)
    refine_time_offset_s: float = param(0.0, "with estimate_time_offset: every this much log time, estimate the "
                                        "offset left in every sweep so far and, when it exceeds twice its standard "
                                        "error, apply it to the IMU stamps from then on. The LiDAR poses keep part "
                                        "of the IMU-driven guess, so one estimate after the run reads only part of "
                                        "a large lag (30 ms -> 23-28 ms); 0 = one estimate after the run, nothing "
                                        "applied", "s", ge=0.0, le=86_400.0)
    time_offset_passes: int = param(2, "with estimate_time_offset: run the log up to this many times, each "
                                    "later pass with the offset found so far applied to the IMU stamps, while "
                                    "the offset left stands out (> 2 ms and > 2 standard errors). One pass reads "
                                    "a lag short (its deskew and keyframes ran on the lagged IMU: 30 ms -> 24-29 "
                                    "ms, the forest loop 1.5 ms short on average); a second pass reads what the "
                                    "first left. Each pass costs a whole run; 1 = one run, the offset reported "
                                    "only", ge=1, le=5)
    max_velocity_mps: float = param(30.0, "reset graph #2 above this velocity (LIO-SAM failure check)", "m/s")
    max_bias: float = param(1.0, "... or above this bias norm")


@dataclass(frozen=True)
class FeatureConfig:
    """Point selection and feature extraction."""

    min_range_m: float = param(1.0, "drop points closer than this (LIO-SAM lidarMinRange)", "m")
    max_range_m: float = param(1000.0, "drop points farther than this (lidarMaxRange)", "m")
    body_crop_box_m: tuple[float, float, float, float, float, float] | None = param(
        (-3.35, -1.15, -2.35, 0.95, 1.15, -0.85), "drop points inside this box of the cloud frame [x_min, y_min, "
        "z_min, x_max, y_max, z_max]: the machine's own body (lidarMinRange shaped to the body; default: the MPD's "
        "4 x 2 x 1.2 m body seen from its OS0 mount, plus 0.15 m); None = off", "m")
    edge_threshold: float = param(1.0, "smoothness above this is an edge candidate (edgeThreshold)")
    surf_threshold: float = param(0.1, "smoothness below this is a planar candidate (surfThreshold)")
    max_edges_per_sector: int = param(20, "edges kept per sector")
    sectors: int = param(6, "sectors per ring (LIO-SAM: 6)", ge=1, le=4096)
    occlusion_jump_m: float = param(0.3, "range jump marking an occlusion", "m")
    parallel_ratio: float = param(0.02, "neighbour range differences above this fraction mark a parallel beam")
    surf_leaf_m: float = param(0.4, "voxel size of the planar cloud (odometrySurfLeafSize)", "m")
    ground_max_angle_deg: float = param(10.0, "no edges on the ground: a point below the sensor whose step to the "
                                        "next ring in its column rises less than this is ground (LeGO-LOAM); on open "
                                        "ground the arcs of the rings otherwise give edges that pose as x, y and yaw "
                                        "information; 0 = off (LIO-SAM)", "deg")
    smoothness: Literal["range", "paper"] = param(
        "range", "range: LIO-SAM's code, (sum of 10 neighbour ranges - 10 r)^2 in m^2; paper: the paper's (LOAM's) "
        "formula |sum(p - p_u)| / (10 |p|), dimensionless, so edge/surf thresholds must be set for its scale")


@dataclass(frozen=True)
class MatchingConfig:
    """Scan-to-map matching."""

    corner_leaf_m: float = param(0.2, "map voxel size for edges (mappingCornerLeafSize)", "m")
    surf_leaf_m: float = param(0.4, "map voxel size for planes (mappingSurfLeafSize)", "m")
    map_radius_m: float = param(50.0, "keyframes within this of the last one form the local map "
                                "(surroundingKeyframeSearchRadius)", "m")
    map_recent_s: float = param(10.0, "plus every keyframe of the last seconds", "s")
    max_iterations: int = param(30, "Gauss-Newton iterations", ge=1, le=1000)
    min_edges: int = param(10, "optimise only with at least this many edge features (edgeFeatureMinValidNum)")
    min_surfs: int = param(100, "... and planar features (surfFeatureMinValidNum)")
    match_without_edges: bool = param(True, "with too few edges, still match the planes (LIO-SAM keeps the IMU guess "
                                      "instead): on open ground the ground plane fixes z, roll and pitch, and the "
                                      "degeneracy remapping holds x, y and yaw at the IMU guess")
    ground_normal_min_z: float = param(0.9, "plane residuals whose map normal has |n_z| above this (ground, within "
                                       "26 deg of vertical) constrain only z, roll and pitch (LeGO-LOAM's split); "
                                       "0 = off (LIO-SAM: every row constrains all six)")
    max_rotation_correction_deg: float = param(2.0, "with an IMU: reject a match that turns the IMU-predicted "
                                               "attitude by more than this (a false match, not a gyro error) and keep "
                                               "the guess; 0 = off (LIO-SAM)", "deg")
    max_tilt_correction_deg: float = param(2.0, "a match that rotation gate rejects keeps its roll, pitch and z when "
                                           "its tilt correction (the gravity direction's) is within this: the turn "
                                           "beyond the gate is yaw, which an open field's far poles give a degree "
                                           "off, while the ground holds tilt and z; the IMU's yaw, x and y stay. "
                                           "0 = the whole match rejected (z walks, docs/simulation.md)", "deg",
                                           ge=0.0, le=90.0)
    tilt_after_rejections: int = param(2, "max_tilt_correction_deg from the n-th sweep in a row the rotation gate "
                                       "turns down: a single rejection (a wheel log's second sweep) keeps the "
                                       "whole guess as before, a lock-out does not", ge=1, le=1000)
    degeneracy_eigen_threshold: float = param(100.0, "eigenvalues of J^T J below this are degenerate directions")
    converge_rot_deg: float = param(0.05, "convergence: rotation update", "deg")
    converge_trans_cm: float = param(0.05, "convergence: translation update", "cm")
    max_nn_sq_dist_m2: float = param(1.0, "neighbours farther than this (squared) are not used", "m^2")
    keyframe_density_m: float = param(2.0, "keyframe positions voxelised at this before choosing the local map "
                                      "(surroundingKeyframeDensity)", "m")
    local_map_selection: Literal["nearest", "oldest"] = param(
        "nearest", "one keyframe per keyframe_density voxel of the surrounding key poses: nearest = the keyframe "
        "nearest to the voxel centroid (LIO-SAM); oldest = the first keyframe in the voxel (earlier rule)")
    plane_min_spread_m: float = param(0.1, "a plane is rejected when its 5 neighbours spread less than this (std) "
                                      "across their line: the neighbours on one ring arc of far ground are nearly "
                                      "collinear and their normal is arbitrary, which poses as x, y and yaw "
                                      "information; 0 = off (LIO-SAM)", "m")
    min_correspondences: int = param(50, "stop iterating with fewer residuals than this")
    plane_max_offset_m: float = param(0.2, "a plane is rejected when a neighbour is farther from it", "m")
    requery_motion_m: float = param(0.05, "re-query a feature's nearest map neighbours only after it moved more "
                                    "than this since its last query within the sweep's matching (0 = every "
                                    "iteration, as LIO-SAM; the map's voxels are 0.2-0.4 m)", "m", ge=0.0, le=1.0)


@dataclass(frozen=True)
class GraphConfig:
    """Keyframes and the factor graph."""

    keyframe_dist_m: float = param(1.0, "new keyframe after this translation "
                                   "(surroundingkeyframeAddingDistThreshold)", "m")
    keyframe_angle_rad: float = param(0.2, "... or this rotation", "rad")
    prior_variances: tuple[float, float, float, float, float, float] = param(
        (1e-4, 1e-4, 3.141592653589793 ** 2, 1e8, 1e8, 1e8), "first-pose prior variances [rot, trans]: x, y and "
        "yaw free, so GNSS fixes place the whole chain (LIO-SAM); roll and pitch 0.01 rad, the gravity the IMU's "
        "initial attitude is read from (a consumer MEMS's 0.1 m/s^2 turn-on bias tilts it 0.01 rad; LIO-SAM's "
        "1e-2 rad^2 let one GNSS factor on a 2.2 m mast tilt the whole chain 10 deg: docs/simulation.md)")
    anchored_prior_variances: tuple[float, float, float, float, float, float] = param(
        (1e-4, 1e-4, 1e-6, 1e-6, 1e-6, 1e-6), "... when anchor_start applies: the first keyframe is the map's origin "
        "and heading, and GNSS factors enter only once the drift since the start exceeds gps.pose_cov_threshold_m2")
    anchor_start: Literal["with_wheels", "always", "never"] = param(
        "with_wheels", "anchor the first keyframe (anchored_prior_variances) instead of LIO-SAM's free start; "
        "with_wheels: when wheel factors say how far the chain can have drifted (docs/simulation.md, \"Open field\"), "
        "whatever the GNSS gate (without wheels an anchored start held the open line's IMU drift against the fixes: "
        "no wheels, float GNSS, tuning seeds 0-2, online APE 50 / 33 / 34 m anchored, 7.3 / 15 / 7.5 m free)")
    odometry_variances: tuple[float, float, float, float, float, float] = param(
        (1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4), "odometry between-factor variances [rot, trans]")
    factorization: Literal["QR", "CHOLESKY"] = param("QR", "iSAM2 factorisation; gtsam 4.3's CHOLESKY rejects "
                                                     "the loose prior")
    relinearize_threshold: float = param(0.1, "iSAM2 relinearizeThreshold")
    relinearize_skip: int = param(1, "iSAM2 relinearizeSkip")
    extra_updates: int = param(5, "extra iSAM2 update() calls after a loop or GNSS factor")
    degenerate_odometry_sigma: float = param(0.0, "odometry factor sigma along the directions scan-to-map left to "
                                             "the IMU at the new keyframe (rad and m; LIO-SAM: the odometry_variances "
                                             "on all six): GNSS and loop factors can bend the chain there (e.g. 0.1 "
                                             "with gps.rtk_max_variance_m2); 0 = off: with LIO-SAM's 1 m^2 fixes and a "
                                             "map yaw fitted on a drifting start it made open-field runs worse")


@dataclass(frozen=True)
class LoopConfig:
    """Radius-search loop closure."""

    enabled: bool = param(True, "radius-search loop closure (loopClosureEnableFlag); the CLI's --no-loop sets it "
                          "to false")
    search_radius_m: float = param(15.0, "candidate keyframes within this (historyKeyframeSearchRadius)", "m")
    time_gap_s: float = param(30.0, "... and older than this (historyKeyframeSearchTimeDiff)", "s")
    neighbours: int = param(25, "submap of +/- this many keyframes (historyKeyframeSearchNum)")
    min_eigenvalue: float = param(100.0, "... and the aligned clouds pin all six degrees of freedom: smallest "
                                  "eigenvalue of the point-to-plane J^T J (ground rows: z, roll, pitch only) at least "
                                  "this (slam.matching.degeneracy_eigen_threshold's scale); on bare ground ICP slides "
                                  "with a low fitness; 0 = fitness only (LIO-SAM)")
    fitness_threshold_m2: float = param(0.3, "accept ICP if mean squared NN distance below "
                                        "(historyKeyframeFitnessScore)", "m^2")
    icp_max_correspondence_m: float = param(30.0, "ICP max correspondence distance (first stage)", "m")
    interval_s: float = param(1.0, "at most one loop search per this much log time (loopClosureFrequency 1 Hz)", "s")
    leaf_m: float = param(0.4, "voxel size of the loop source and target clouds", "m")
    min_source_points: int = param(300, "skip the check with a smaller source cloud")
    min_target_points: int = param(1000, "... or target submap")
    icp_iterations: int = param(100, "ICP iterations")


@dataclass(frozen=True)
class GpsConfig:
    """GNSS factors."""

    enabled: bool = param(True, "add GNSS factors when the log has GNSS; the CLI's --no-gps sets it to false")
    pose_cov_threshold_m2: float = param(25.0, "only when the x/y pose variance exceeds this (poseCovThreshold)", "m^2")
    gps_cov_threshold_m2: float = param(2.0, "drop fixes with a larger variance (gpsCovThreshold)", "m^2")
    min_spacing_m: float = param(5.0, "distance between GNSS factors", "m")
    max_time_diff_s: float = param(0.2, "fix must be this close to the keyframe", "s")
    min_travel_m: float = param(5.0, "no GNSS factor before the first-to-last keyframe distance reaches this", "m")
    use_elevation: bool = param(False, "use the GNSS height (useGpsElevation); off = keep the estimated z; the "
                                "lio_sam gate only (the residual gate keeps the chain's z and warns)", "")
    rtk_max_variance_m2: float = param(0.0, "fixes with horizontal variances at most this (e.g. 0.01) are RTK-grade: "
                                       "added whenever the keyframe's x/y variance exceeds the fix's own (not only "
                                       "above pose_cov_threshold_m2), with their own variance (no 1 m^2 floor) and "
                                       "rtk_min_spacing_m apart; 0 = LIO-SAM's rules for every fix (default: the "
                                       "ENU -> map yaw is fitted from the first align_min_travel_m of keyframes, and "
                                       "a drifting start makes tight fixes twist the map)", "m^2")
    rtk_min_spacing_m: float = param(1.0, "distance between RTK-grade GNSS factors", "m")
    align_min_travel_m: float = param(10.0, "travel needed before the ENU -> map yaw alignment is estimated", "m")
    gate: Literal["residual", "lio_sam"] = param(
        "residual", "residual: a GNSS factor enters when the fixes of the last residual_window_s, against the chain "
        "through the ENU -> map alignment re-fitted on every fix so far, disagree with it significantly (the chain "
        "drifted), whatever the chain's own covariance says, with or without wheels; multipath outliers are dropped "
        "against the window's median (slam/gnss_gate.py). lio_sam: LIO-SAM's gate on the pose covariance "
        "(pose_cov_threshold_m2, min_spacing_m, the 1 m^2 floor) with the alignment fitted once")
    align_max_travel_m: float = param(0.0, "residual gate: the alignment is re-fitted on the fixes of the first this "
                                      "many metres of travel (the chain there as corrected so far); 0 = on every "
                                      "fix so far", "m", ge=0.0)
    residual_window_s: float = param(6.0, "residual gate: the fixes of this long before the keyframe: a robust line "
                                     "through their residuals gives the chain's offset now and its drift rate", "s",
                                     gt=0.0)
    residual_min_fixes: int = param(5, "residual gate: at least this many inlier fixes in the window", ge=3)
    residual_outlier_sigmas: float = param(3.0, "residual gate: a fix whose residual is further than this many of its "
                                           "sigmas (plus residual_floor_m) from the line is an outlier (multipath)",
                                           gt=0.0)
    residual_drift_sigmas: float = param(3.0, "residual gate: the offset now must exceed this many of its sigmas ...",
                                         gt=0.0)
    residual_min_correction_m: float = param(0.1, "... and this, for a factor (the chain agrees with GNSS otherwise)",
                                             "m", ge=0.0)
    residual_floor_m: float = param(0.05, "residual gate: sigma floor of a factor (fix biases that do not average)",
                                    "m", ge=0.0)
    residual_min_spacing_m: float = param(1.0, "residual gate: distance between GNSS factors", "m", ge=0.0)
    residual_gate_chi2: float = param(9.0, "residual gate, with wheels: an offset beyond this chi-square of (its "
                                      "sigma^2 + the chain's real drift sigma^2) is held multipath, not drift", gt=0.0)
    residual_chain_drift_fraction: float = param(0.03, "residual gate, with wheels: the chain's real drift sigma per "
                                                 "metre since the last GNSS factor (calibrated wheels and the gyro)",
                                                 "m/m", ge=0.0)
    residual_chain_floor_m: float = param(0.3, "... plus this", "m", ge=0.0)
    residual_velocity_correction: bool = param(True, "residual gate, without wheels: when a factor moved the keyframe, "
                                               "graph #2 restarts with the fixes' drift rate removed from its velocity")
    residual_huber_k: float = param(1.345, "residual gate: Huber kernel width of the factors (sigmas; 0 = none)",
                                    ge=0.0)
    ins: Literal["off", "without_wheels", "always"] = param(
        "off", "GNSS/INS (slam/gnss_ins.py): fixes as antenna-position factors in graph #2 (the IMU "
        "preintegration graph), so they steer its velocity and accelerometer bias, with the ENU -> map alignment "
        "fixed once from the fixes' own course against the chain's forward-axis heading; the online pose is then "
        "graph #2's fused pose and graph #1 gets no GNSS factors. without_wheels: only when no wheel odometry is used. "
        "Off by default: it does not hold the open line without wheels (float GNSS) yet and costs the yard "
        "(docs/simulation.md, issue 28)")
    ins_align_travel_m: float = param(5.0, "GNSS/INS: the fixes' travel along their course before the alignment is "
                                      "fixed", "m", gt=0.0, le=100.0)
    ins_align_max_turn_deg: float = param(30.0, "GNSS/INS: ... against the mean heading over a stretch whose chain "
                                          "heading spans at most this; one that turns more is aligned pair by pair "
                                          "(each pair of fixes against the heading at its middle)", "deg", gt=0.0,
                                          le=180.0)
    ins_jump_m: float = param(0.8, "GNSS/INS alignment: a step of the fixes (median of 3 to median of 3) this much "
                              "beyond the chain's own motion starts a new multipath segment; the course is taken "
                              "from pairs of fixes inside one segment", "m", gt=0.0, le=100.0)
    ins_origin_s: float = param(2.0, "GNSS/INS: the alignment's translation puts the fixes of this long after the "
                                "first sweep on the chain's antenna there", "s", gt=0.0, le=60.0)
    ins_gate_chi2: float = param(13.8, "GNSS/INS: a fix enters when its innovation's squared Mahalanobis distance "
                                 "(graph #2's marginal antenna covariance + the fix's) is at most this (2 dof; "
                                 "13.8: 0.1 %)", gt=0.0, le=1000.0)
    ins_trend_window_s: float = param(8.0, "GNSS/INS: a fix enters when it agrees with a robust line through the "
                                      "innovations of the fixes accepted in this long",
                                      "s", gt=0.0, le=120.0)
    ins_trend_min_fixes: int = param(10, "GNSS/INS: ... when at least this many were accepted in it (else the "
                                     "chi-square gate on graph #2's covariance decides)", ge=3, le=10000)
    ins_trend_of: Literal["accepted", "all"] = param(
        "all", "GNSS/INS: the trend line is fitted on the accepted fixes and decides alone once there are "
        "ins_trend_min_fixes of them (accepted), or on every fix, a fix entering when the chi-square gate or the trend "
        "takes it (all: a chain that drifts faster than its covariance says is followed sooner, and so is a long "
        "multipath jump)")
    ins_trend_sigmas: float = param(3.0, "GNSS/INS: ... within this many of its sigmas", gt=0.0, le=100.0)
    ins_trend_floor_m: float = param(0.3, "GNSS/INS: ... plus this", "m", ge=0.0, le=10.0)
    ins_step_fixes: int = param(5, "GNSS/INS: this many rejected fixes in a row that agree with each other are a "
                                "multipath step, taken off the later fixes (0 = never)", ge=0, le=1000)
    ins_max_offset_m: float = param(3.5, "GNSS/INS: a multipath offset beyond this is no step (the chain drifted): "
                                    "not taken", "m", gt=0.0, le=100.0)
    ins_reacquire_s: float = param(10.0, "GNSS/INS: after this long of fixes rejected without a break, take them "
                                   "again (the chain diverged; multipath jumps last 2-8 s)", "s", gt=0.0, le=600.0)
    ins_huber_k: float = param(1.345, "GNSS/INS: Huber kernel width of the factors (sigmas; 0 = none)", ge=0.0,
                               le=100.0)
    ins_sigma_floor_m: float = param(0.05, "GNSS/INS: floor of a fix's horizontal sigma", "m", ge=0.0, le=10.0)
    ins_vertical_sigma_m: float = param(100.0, "GNSS/INS: sigma of the factors' height (the chain's own: the ground "
                                        "holds z)", "m", gt=0.0, le=1e4)
    ins_degenerate_sigma: float = param(10.0, "GNSS/INS, once aligned: graph #2's sigma (m, rad) of a degenerate "
                                        "scan-to-map pose along its free directions (slam.imu.degenerate_pose_sigma "
                                        "otherwise): the match there only repeats the IMU's prediction, and counted "
                                        "as a measurement it shrinks the covariance the fixes are gated against",
                                        gt=0.0, le=1e4)
    ins_acc_noise: float = param(0.2, "GNSS/INS, once aligned: graph #2's accelerometer noise density, at least "
                                 "(the machine's vibration and a drifting attitude's gravity leak, which a bench "
                                 "figure or a stationary stretch does not show)", "m/s^2/sqrt(Hz)", gt=0.0, le=10.0)
    ins_acc_bias_walk: float = param(0.1, "GNSS/INS, once aligned: graph #2's accelerometer bias random walk, at "
                                     "least (a tilt error acts as a slowly changing bias the fixes then track)",
                                     "m/s^3", gt=0.0, le=10.0)
    ins_marginal_restarts: bool = param(True, "GNSS/INS, once aligned: graph #2's periodic restarts start from its "
                                        "marginals (what the fixes taught carries over), whatever "
                                        "slam.imu.reset_priors says")
    ins_max_fix_age_s: float = param(0.3, "GNSS/INS: a fix older than this at its key is dropped (it is moved to the "
                                     "key's stamp by the chain's velocity)", "s", gt=0.0, le=5.0)
    track: Literal["never", "without_wheels"] = param(
        "without_wheels", "without_wheels: when no wheel odometry is used, the x, y that a degenerate scan-to-map "
        "leaves to the IMU come from a Kalman filter on the fixes (slam/gnss_track.py), as the wheels would "
        "otherwise give them; never: IMU dead reckoning there (LIO-SAM)")
    track_cov_threshold_m2: float = param(
        25.0, "GNSS track: it takes fixes up to this horizontal variance, beyond gps_cov_threshold_m2 (which "
        "drops single-point fixes of 1.5 m): without wheels, on bare ground, the alternative is IMU dead "
        "reckoning (the open line with single-point fixes: 15-135 m online APE with them dropped)", "m^2",
        gt=0.0, le=10_000.0)
    track_accel_sigma: float = param(0.3, "GNSS track: the filter's white acceleration (a skid-steer at walking "
                                     "pace)", "m/s^2", gt=0.0, le=20.0)
    track_max_gap_s: float = param(2.0, "GNSS track: without a fix taken for this long (an outage) the sweeps keep "
                                   "the chain's own x, y, and the filter starts again at the next fix", "s", gt=0.0,
                                   le=60.0)
    track_step_fixes: int = param(4, "GNSS track: this many rejected fixes in a row that agree are a multipath step "
                                  "(on or off), held as an offset", ge=2, le=100)
    track_sigma_floor_m: float = param(
        0.05, "GNSS track: floor of a fix's horizontal sigma in the filter; an RTK fix's 2 cm is honest about the "
        "antenna, but the constant-velocity model does not follow the antenna that closely (it sways with the "
        "base's roll on rough ground): with 2 cm the filter gates the fixes out and holds them as steps",
        "m", ge=0.0, le=10.0)
    track_provisional_travel_m: float = param(
        3.0, "GNSS track: until the alignment (ins_align_travel_m of travel) is fixed, a provisional one from "
        "this much travel of the fixes carries x, y (the chain dead-reckons on the IMU before it); replaced "
        "once, graph #2 restarting at the switch; 0: none", "m", ge=0.0, le=100.0)
    track_lag_check_s: float = param(
        2.0, "GNSS track: after a multipath step, the velocity of this long of fixes (a straight line through "
        "them) is compared with the filter's just before the step; when they disagree (chi-square, 2 dof) the "
        "filter was lagging, not the fixes jumping, and the held offset is dropped; 0: off", "s", ge=0.0, le=10.0)
    track_box_check_s: float = param(
        8.0, "GNSS track: a multipath step that leaves an offset held is tested, 2 s after it, against the "
        "offset-free hypothesis: the filter followed a jump (or a held jump's change) that began up to this "
        "long before, the step is its end and the fixes are clean now (they fit a smooth track with a box "
        "offset ending at the step better than with the offset held); then the offset goes to zero and the "
        "filter to the fixes' track; 0: off", "s", ge=0.0, le=30.0)
    track_model: Literal["steps", "hypotheses"] = param(
        "hypotheses", "GNSS track: the filter on the fixes. hypotheses: the multipath offset is a state and its "
        "changes (a jump on, changed, off) are hypotheses weighted by their likelihood, the likeliest kept "
        "(slam/gnss_bank.py); steps: one filter whose gate and step rules decide each jump once "
        "(track_step_fixes, track_lag_check_s, track_box_check_s)")
    track_jump_sigma_m: float = param(1.5, "GNSS track, hypotheses: prior sigma per axis of a multipath jump's "
                                      "offset", "m", gt=0.0, le=20.0)
    track_jump_on_hz: float = param(0.1, "GNSS track, hypotheses: prior rate of a multipath jump coming on (or "
                                    "changing)", "1/s", gt=0.0, le=5.0)
    track_jump_off_hz: float = param(0.25, "GNSS track, hypotheses: prior rate of a jump that is on going off",
                                     "1/s", gt=0.0, le=5.0)
    track_hypotheses: int = param(20, "GNSS track, hypotheses: how many are kept after each fix", ge=1, le=500)
    track_both_axes: bool = param(
        True, "GNSS track: a sweep whose match left a horizontal direction free takes x and y both from the track; "
        "on bare ground the other horizontal direction is matched against a map the track itself laid (on the "
        "open line without wheels it held the antenna up to 4.3 m off the track); false: only the free directions")
    track_level_antenna: bool = param(
        False, "GNSS track: the filter tracks the antenna as if the base were level: each fix less the antenna's "
        "sway with the base's roll and pitch (the chain's attitude at the fix; a 2.2 m mast sways +-0.2 m "
        "across the course on rough ground, faster than a constant-velocity model follows), the sweep's own "
        "sway put back on the track; false: the antenna's fixes as they are. Off by default: RTK open line "
        "lower on 11 of 14 tuning seeds by 2-8 mm, but report RTK seed 3 fell into a z walk (docs/simulation.md)")


@dataclass(frozen=True)
class MapQualityConfig:
    """Map quality without ground truth: mean map entropy and mean plane variance (Razlaw et al. 2015)."""

    enabled: bool = param(True, "compute mean map entropy and mean plane variance of the final map")
    radius_m: float = param(0.3, "neighbourhood radius around each evaluated map point", "m")
    min_neighbours: int = param(5, "skip points with fewer neighbours within the radius")
    max_neighbours: int = param(30, "use at most this many nearest neighbours within the radius")
    max_points: int = param(10000, "evaluate at most this many (evenly spread) map points")


@dataclass(frozen=True)
class MountCheckConfig:
    """The LiDAR mount's pitch and yaw error from the final trajectory's motion (slam/mount_check.py):
    a ground vehicle moves along its base x axis, so over moving, nearly straight stretches the motion's
    direction in the estimated base frame shows how far /tf_static's mount is rotated."""

    enabled: bool = param(True, "estimate the mount's pitch and yaw error after the run (mount_check in metrics.json)")
    apply: bool = param(True, "lio: when the check flags the mount and slam.sensor.mount_rpy_correction_deg is not "
                        "set, run the log once more with the correction (the base_link poses, the wheel and GNSS "
                        "factors read the corrected mount; twice the run time on such a log; the warning stays)")
    apply_max_sigma_deg: float = param(0.25, "... and only when every flagged angle is known to this standard error "
                                       "or better (a heading that drifts, no wheels on open ground, reads the "
                                       "motion 3-9 deg off at 2-3 deg sigmas; with wheels or structure the field "
                                       "profile's 0.4-0.5 deg read at 0.07-0.12 deg)", "deg", gt=0.0, le=10.0)
    span_s: float = param(1.0, "each motion sample is the chord over this long around a pose", "s", gt=0.0, le=10.0)
    min_speed_mps: float = param(0.3, "samples slower than this are left out (standing, creeping)", "m/s",
                                 ge=0.0, le=10.0)
    max_yaw_rate_rad_s: float = param(0.2, "samples turning faster than this are left out (a skid-steer side-slips "
                                      "in turns; the simulated scenes' truth moved within 0.1 deg of its x axis up "
                                      "to 0.2 rad/s, and 0.2 leaves the 20 m loop enough samples)", "rad/s",
                                      gt=0.0, le=3.0)
    blocks: int = param(10, "contiguous time blocks of the delete-one-block jackknife", ge=2, le=100)
    min_samples: int = param(30, "fewer samples (poses of the final trajectory) than this, or than 2 x blocks: "
                             "verdict insufficient", ge=1)
    min_distance_m: float = param(3.0, "less straight motion than this: verdict insufficient", "m", ge=0.0)
    flag_deg: float = param(0.2, "flag a pitch or yaw error above this ...", "deg", ge=0.0, le=90.0)
    flag_sigmas: float = param(3.0, "... and above this many standard errors", ge=0.0, le=100.0)


@dataclass(frozen=True)
class GroundMountConfig:
    """The LiDAR mount's roll and pitch error from the ground around the machine in the first sweeps
    (slam/ground_mount.py): the base frame stands parallel to the ground under the wheels, so the ground
    ring's plane, put into base axes through /tf_static, is tilted by the mount's error when the ring is
    the footprint's plane; its sigma says when it is not (slope spread, bend) and the check stays silent."""

    enabled: bool = param(True, "fit the ground in the first sweeps before the run (mount_check.ground in "
                          "metrics.json)")
    apply: bool = param(True, "correct /tf_static's roll/pitch of the LiDAR mount by the ground's reading when it is "
                        "flagged (a warning names both; the field terrain's waves never open the gate: 171 of 171 "
                        "matrix logs not measurable); slam.sensor.mount_rpy_correction_deg, when set, wins")
    span_s: float = param(0.5, "the sweeps within this many seconds of the log's first LiDAR sweep (the machine "
                          "standing or slow; a sweep without returns is passed over)", "s", ge=0.0, le=10.0)
    max_sweeps: int = param(5, "at most this many sweeps", ge=1, le=100)
    max_points_per_sweep: int = param(10_000, "every k-th point of a denser sweep, so that at most this many are "
                                      "read (an OS0-128 x 1024 sweep's 80,000 cost ~0.5 s CPU over 5 sweeps; "
                                      "OS0-32 x 512 is read whole)", ge=500)
    ring_m: tuple[float, float] = param((2.0, 8.0), "horizontal distance from the base origin of the ground used "
                                        "[inner, outer]: beyond the body, near enough to be the footprint's "
                                        "ground", "m", gt=0.0, le=50.0)
    min_points: int = param(500, "fewer ground points in the ring than this: not measurable", ge=3)
    max_residual_m: float = param(0.05, "heights scattering more than this about the plane (vegetation, "
                                  "clutter): not measurable; a third of it is the floor of the fit's 3-sigma "
                                  "cut", "m", gt=0.0, le=1.0)
    min_inlier_fraction: float = param(0.5, "less of the ring on the plane than this: not measurable",
                                       ge=0.0, le=1.0)
    cell_m: float = param(0.5, "cell of the slope spread's mean heights", "m", gt=0.0, le=5.0)
    slope_baseline_m: float = param(1.0, "distance of the cells compared for the local slope (half the MPD's "
                                    "wheelbase: on the field terrain's 2.7-3.7 m waves 2 m saw a third of the "
                                    "slope under the base, the readings off by up to 9.6 sigma; 1 m: 3.3)", "m",
                                    gt=0.0, le=10.0)
    max_sigma_deg: float = param(0.15, "an axis whose sigma (fit, slope spread, bend) is above this is not read",
                                 "deg", gt=0.0, le=90.0)
    flag_deg: float = param(0.15, "flag a roll or pitch error above this ...", "deg", ge=0.0, le=90.0)
    flag_sigmas: float = param(3.0, "... and above this many sigma", ge=0.0, le=100.0)


@dataclass(frozen=True)
class WheelCalibrationConfig:
    """Online calibration and gating of the wheel odometry (slam/wheel_calibration.py) and the
    wheel_health verdict (slam/wheel_health.py)."""

    enabled: bool = param(True, "estimate the effective track factor, L/R mismatch and yaw-rate offset against the "
                          "gyro (and the scale against non-degenerate LiDAR odometry) and use the calibrated wheels")
    bin_s: float = param(0.2, "wheel increments are compared with the gyro over bins of this length", "s", gt=0.0)
    prior_sigmas: tuple[float, float, float] = param((0.5, 0.05, 0.002), "prior sigmas of the track factor "
                                                     "(around 1), the L/R term a (1/m, around 0) and the yaw-rate "
                                                     "offset (rad/s, around 0: encoders read zero at standstill, so "
                                                     "the offset is the gyro's bias left after the standing start)")
    yaw_rate_sigma_rad_s: float = param(0.01, "reference sigma of a bin's wheel-minus-model yaw rate (good wheels "
                                        "and the gyro); the yaw hold is scaled by (this / the guess's yaw-rate "
                                        "sigma)^2: the gyro blend's with a standing start, else the calibrated "
                                        "wheels' (the measured residual over the track factor squared)", "rad/s",
                                        gt=0.0)
    gyro_yaw_rate_sigma_rad_s: float = param(0.002, "sigma of the gyro's bin yaw rate (bias left after the standing "
                                             "start and the fit, vibration) when it is blended with the calibrated "
                                             "wheels' by inverse variance; 0 = the wheels' yaw alone", "rad/s", ge=0.0)
    gate_chi2: float = param(9.0, "reject a bin whose normalised innovation squared exceeds this (1 dof; 9 = 3 "
                             "sigma); its yaw comes from the gyro", gt=0.0)
    warmup_bins: int = param(25, "bins before the gate and the yaw-hold scaling act", ge=0)
    min_yaw_quality: float = param(0.05, "lower bound of the yaw-hold scale", gt=0.0, le=1.0)
    stationary_speed_mps: float = param(0.05, "the wheels' speed below which the start counts as standing (the "
                                        "gyro's mean there is its bias)", "m/s", ge=0.0)
    straight_bias_window_s: float = param(4.0, "without a standing start, the gyro's bias is its mean over the "
                                          "first stretch this long (1 s sub-bins) where the machine drives straight "
                                          "by the wheels and the gyro (8 s: line begun mid-drive, tuning seeds, end "
                                          "drift 0.71 / 1.60 m against 0.51 / 0.54 m); 0 = off (the gyro then not "
                                          "blended)", "s", ge=0.0)
    straight_min_speed_mps: float = param(0.3, "... every sub-bin driving at least this fast", "m/s", gt=0.0)
    straight_max_yaw_rate_rad_s: float = param(0.02, "... the wheels' raw yaw rate at most this over the stretch "
                                               "(L/R mismatch: 2 % is 12.5 mrad/s at 1 m/s) and 2.5x this in every "
                                               "sub-bin", "rad/s", gt=0.0)
    straight_max_gyro_spread_rad_s: float = param(0.02, "... the sub-bins' gyro means within this of each other",
                                                  "rad/s", gt=0.0)
    straight_bias_sigma_rad_s: float = param(0.002, "... the bias's 1 sigma (a gentle arc the guards let through), "
                                             "with the standard error of the sub-bins' mean", "rad/s", gt=0.0)
    scale_prior_sigma: float = param(0.05, "prior sigma of the scale error (around 0)", gt=0.0)
    scale_distance_sigma_m: float = param(0.02, "sigma of a LiDAR keyframe distance for the scale fit", "m", gt=0.0)
    scale_max_turn_rad: float = param(0.02, "keyframe steps turning more than this do not enter the scale fit "
                                      "(a skid-steer's tracks slip in turns; the simulated yard circle's +6 % "
                                      "over-read came from its wet patch instead, which scale_gate_chi2 handles)",
                                      "rad", ge=0.0)
    scale_min_distance_m: float = param(0.5, "keyframe steps shorter than this do not enter the scale fit", "m", ge=0.0)
    gnss_scale_min_span_m: float = param(5.0, "when no LiDAR step measured the scale (bare ground), wheel_health "
                                         "reads it from the GNSS fixes against the calibrated wheel track after the "
                                         "run (slam/wheel_gnss_scale.py) once the fixes spread this far (RMS from "
                                         "their centroid); 0 = never", "m", ge=0.0, le=10_000.0)
    gnss_scale_correlation_s: float = param(10.0, "... its sigma is at least what the fixes' own sigmas give with one "
                                            "independent error per this much time (RTK float and multipath errors "
                                            "stay correlated for seconds to minutes; 0 = every fix independent)",
                                            "s", ge=0.0, le=3600.0)
    scale_gate_chi2: float = param(9.0, "a distance step whose wheel-minus-LiDAR residual against the fit of the "
                                   "others exceeds this normalised square (1 dof) is slip (soft or wet ground: the "
                                   "wheels turn, the ground does not move as far), not scale: left out of the fit "
                                   "and counted in wheel_health", gt=0.0)
    track_width_m: float = param(1.6, "the track width the odometry node divides by (robot.track_width_m): turns "
                                 "the fitted L/R term into a radius mismatch", "m", gt=0.0)
    flag_lr_mismatch: float = param(0.01, "wheel_health flags an estimated |L/R mismatch| above this (fraction)",
                                    ge=0.0)
    flag_track_factor: float = param(0.25, "... |track factor - 1| above this (1.1-1.2: a calibrated machine)", ge=0.0)
    flag_scale: float = param(0.015, "... |scale error| above this (fraction)", ge=0.0)
    flag_rejected_fraction: float = param(0.1, "... a fraction of rejected bins above this by flag_sigmas binomial "
                                          "sigmas (at this rate over the bins so far)", ge=0.0, le=1.0)
    flag_sigmas: float = param(3.0, "... only estimates this many sigmas away from the nominal value", ge=0.0)


@dataclass(frozen=True)
class ImuAxesConfig:
    """Whether /tf_static's mounts put the IMU's axes where the machine's turns say (slam/imu_axes.py):
    a ground vehicle turns about base_link z."""

    enabled: bool = param(True, "check the IMU's axes against the machine's turns before the run (lio stops with an "
                          "input error naming /tf_static when they are rotated)")
    window_s: float = param(5.0, "the gyro's net rotation over windows this long (bumps and sways net out: the open "
                            "line's 3 m terrain waves pitch a 2 s window by up to 0.14 rad)", "s", gt=0.0, le=60.0)
    min_window_rad: float = param(0.25, "windows that turned less than this are left out (a turn at 0.1 rad/s is 0.5 "
                                  "rad a window)", "rad", ge=0.0, le=3.2)
    min_turn_rad: float = param(1.0, "less turning than this over the log: verdict not measurable", "rad",
                                ge=0.0, le=100.0)
    max_angle_deg: float = param(30.0, "the turn axis further from base_link z than this: verdict rotated (slopes "
                                 "do not move it: the machine turns about its own up axis)", "deg", gt=0.0, le=90.0)


@dataclass(frozen=True)
class WheelClockConfig:
    """The wheel odometry's stamp offset against the gyro's, from the log's turns before the run
    (slam/wheel_clock.py): a host- or PLC-stamped odometry is often tens of ms late."""

    enabled: bool = param(True, "estimate the wheel stamps' offset against the gyro before the run (wheel_clock in "
                          "metrics.json)")
    apply: bool = param(True, "subtract a flagged offset from the wheel stamps for the run (a warning says so; "
                        "slam.wheel_odom.time_offset_s is the known one)")
    window_s: float = param(0.2, "yaw rates are means over this long (the pickups' noise averaged down)", "s",
                            gt=0.0, le=2.0)
    grid_s: float = param(0.02, "sample spacing of the fit", "s", gt=0.0, le=1.0)
    max_lag_s: float = param(0.4, "offsets searched: +- this", "s", gt=0.0, le=2.0)
    lag_step_s: float = param(0.005, "spacing of the searched offsets (refined between them)", "s", gt=0.0, le=0.1)
    blocks: int = param(8, "contiguous time blocks of the jackknife standard error", ge=2, le=100)
    max_sigma_s: float = param(0.05, "a standard error above this: verdict not measurable (a straight line, a "
                               "circle at constant speed)", "s", gt=0.0, le=1.0)
    flag_s: float = param(0.04, "flag an offset above this ... (the simulated skid-steer's wheels lead its body's "
                          "yaw by 7-17 ms on firm ground, 27 ms on the soft circle: the plant, not the clock)", "s",
                          ge=0.0, le=1.0)
    flag_sigmas: float = param(3.0, "... and above this many standard errors", ge=0.0, le=100.0)
    min_track_factor: float = param(0.2, "the wheels' yaw must follow the gyro's by a factor in [this, 1 / this] "
                                    "(the skid), else verdict not measurable (a frozen pose, another topic)",
                                    gt=0.0, lt=1.0)


@dataclass(frozen=True)
class WheelOdomConfig:
    """Wheel odometry (the log's wheel_odom role, odom -> base_link): a relative-pose factor between
    consecutive keyframes in graph #1 with a skid-steer noise model (1 sigma, base_link axes), and
    x, y and yaw of each sweep's guess (docs/simulation.md, "Open field")."""

    enabled: bool = param(True, "use the log's wheel odometry (when it has one): factors between keyframes, the "
                          "sweep guess (guess), graph #2 restarts (restart_imu_after_m)")
    forward_fraction: float = param(0.03, "forward sigma per metre driven (slip, effective wheel radius)", "m/m")
    forward_floor_m: float = param(0.01, "forward sigma floor per keyframe step", "m")
    lateral_fraction: float = param(0.01, "lateral sigma per metre driven (skid-steer: nearly non-holonomic)", "m/m")
    lateral_floor_m: float = param(0.005, "lateral sigma floor per keyframe step", "m")
    yaw_fraction: float = param(0.05, "yaw sigma per radian turned (track slip in turns; on a straight line both "
                                "sides turn alike)", "rad/rad")
    yaw_floor_rad: float = param(0.002, "yaw sigma floor per keyframe step", "rad")
    tilt_sigma_rad: float = param(0.5, "roll and pitch sigma (planar odometry: left to the LiDAR ground)", "rad")
    z_sigma_m: float = param(1.0, "vertical sigma (planar odometry: left to the LiDAR ground); small (0.005) it "
                             "holds the base to its x-z plane and bends the chain against a mount pitch error: the "
                             "open line's end z goes, closed paths climb (sample logs +20 / +8 % APE; "
                             "docs/simulation.md)", "m")
    lidar_degenerate_sigma: float = param(0.0, "with wheel factors, the LiDAR odometry factor's sigma along the "
                                          "directions scan-to-map left to the IMU, when graph.degenerate_odometry_"
                                          "sigma is 0 (rad and m; 0 = the odometry_variances; on the open-field log "
                                          "1.0 gave 3.1 m APE online against 0.25 m)")
    guess: bool = param(True, "x, y and yaw of each sweep's initial guess from the wheels (z, roll, pitch from the "
                        "IMU): where bare ground leaves them free, the online pose follows the wheels")
    yaw_information: float = param(1e4, "with the wheel guess, information holding the matched yaw towards it, "
                                   "in J^T J's units (m^2): a few far poles move the yaw part of the way, walls "
                                   "and trees (far more) are not held; 0 = off", "m^2")
    pivot_max_gap_s: float = param(0.5, "with the wheel guess, when the last mapped sweep is at most this long "
                                   "ago, the guess is blended as the base and scan-to-map turns about the base "
                                   "origin, so the x and y it holds are the base's; 0 = the sensor's (LIO-SAM)", "s")
    max_rotation_correction_deg: float = param(0.0, "with the wheel guess, the scan-to-map rotation gate instead "
                                               "of matching.max_rotation_correction_deg (0 = that one); 1 halves the "
                                               "open-field APE but wrecks the sample logs (slip: the wheels turn "
                                               "wrongly, the gate then rejects the right match)", "deg")
    calibration: WheelCalibrationConfig = section(WheelCalibrationConfig, "online calibration, gating, health")
    time_offset_s: float = param(0.0, "known wheel-odometry clock lag: subtracted from every wheel stamp before "
                                 "anything else (the clock check, slam.wheel_odom.clock, tells the value)", "s",
                                 ge=-1.0, le=1.0)
    clock: WheelClockConfig = section(WheelClockConfig, "the wheel stamps' offset against the gyro's")
    restart_imu_after_m: float = param(0.02, "restart graph #2 from graph #1's pose and the wheels' velocity when "
                                       "the wheel factor moved the keyframe by more than this (negative: never)", "m")


@dataclass(frozen=True)
class SlamConfig:
    """The LIO-SAM-style SLAM replay (and the kiss-icp peer's choice)."""

    method: Literal["lio", "kiss-icp"] = param("lio", "SLAM method: lio (this project's LIO-SAM replay) or "
                                               "kiss-icp (peer); the CLI's --method sets it")
    table_trajectory: Literal["online", "smoothed"] = param(
        "online", "trajectory in Table I and the CLI summary: online (each sweep's pose when it was processed, what "
        "the paper's real-time system had) or smoothed (re-anchored to the final loop-corrected keyframes)")
    mapping_interval_s: float = param(0.15, "process a sweep only if this much later than the last "
                                      "(mappingProcessInterval)", "s")
    threads: int = param(0, "threads of the lio run: 1 decodes, prepares (range image, feature labels) and maps "
                         "each sweep in turn on one thread, the KD-tree searches too; N >= 2 decode and prepare "
                         "the next sweeps in a reader thread while this one is mapped, loop closure's KD-tree "
                         "searches on N - 1 OpenMP threads (matching's on the mapping thread); 0 = every core the "
                         "process may use. The poses are the same to the bit whatever the number (--threads sets it)",
                         ge=0, le=1024)
    deskew_translation: bool = param(True, "also remove the translation during the sweep (constant velocity); "
                                     "LIO-SAM deskews rotation only")
    gyro_bias_init_s: float = param(0.0, "average the gyro over the first seconds as its bias (0 = off)", "s")
    sensor: SensorConfig = section(SensorConfig, "the LiDAR (OS0 defaults)")
    imu: ImuConfig = section(ImuConfig, "IMU noise, extrinsics and preintegration (graph #2)")
    features: FeatureConfig = section(FeatureConfig, "range image and feature extraction")
    matching: MatchingConfig = section(MatchingConfig, "scan-to-map matching")
    graph: GraphConfig = section(GraphConfig, "keyframes and the factor graph")
    loop: LoopConfig = section(LoopConfig, "loop closure")
    gps: GpsConfig = section(GpsConfig, "GNSS factors")
    wheel_odom: WheelOdomConfig = section(WheelOdomConfig, "wheel odometry factors in graph #1")
    map_quality: MapQualityConfig = section(MapQualityConfig, "map quality without ground truth")
    mount_check: MountCheckConfig = section(MountCheckConfig, "the LiDAR mount's pitch and yaw from the motion")
    imu_axes: ImuAxesConfig = section(ImuAxesConfig, "the IMU's axes in /tf_static against the machine's turns")
    ground_mount: GroundMountConfig = section(GroundMountConfig, "the LiDAR mount's roll and pitch from the "
                                              "ground at the start")
