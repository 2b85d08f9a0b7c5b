"""SLAM parameters. Defaults follow LIO-SAM's params.yaml (shared/docs/lio-sam-reference.md)."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.params import param, section


@dataclass(frozen=True)
class FeatureConfig:
    min_range_m: float = param(1.0, "drop points closer than this (LIO-SAM lidarMinRange)", "m")
    max_range_m: float = param(1000.0, "drop points farther than this (lidarMaxRange)", "m")
    edge_threshold: float = param(1.0, "smoothness above this is an edge candidate (edgeThreshold)")
    surf_threshold: float = param(0.1, "smoothness below this is a planar candidate (surfThreshold)")
    max_edges_per_sector: int = param(20, "edges kept per sector")
    sectors: int = param(6, "sectors per ring")
    occlusion_jump_m: float = param(0.3, "range jump marking an occlusion", "m")
    parallel_ratio: float = param(0.02, "neighbour range differences above this fraction mark a parallel beam")
    surf_leaf_m: float = param(0.4, "voxel size of the planar cloud (odometrySurfLeafSize)", "m")


@dataclass(frozen=True)
class MatchingConfig:
    corner_leaf_m: float = param(0.2, "map voxel size for edges (mappingCornerLeafSize)", "m")
    surf_leaf_m: float = param(0.4, "map voxel size for planes (mappingSurfLeafSize)", "m")
    map_radius_m: float = param(50.0, "keyframes within this of the last one form the local map "
                                "(surroundingKeyframeSearchRadius)", "m")
    map_recent_s: float = param(10.0, "plus every keyframe of the last seconds", "s")
    max_iterations: int = param(30, "Gauss-Newton iterations")
    min_edges: int = param(10, "optimise only with at least this many edge features (edgeFeatureMinValidNum)")
    min_surfs: int = param(100, "... and planar features (surfFeatureMinValidNum)")
    degeneracy_eigen_threshold: float = param(100.0, "eigenvalues of J^T J below this are degenerate directions")
    converge_rot_deg: float = param(0.05, "convergence: rotation update", "deg")
    converge_trans_cm: float = param(0.05, "convergence: translation update", "cm")
    max_nn_sq_dist_m2: float = param(1.0, "neighbours farther than this (squared) are not used", "m^2")
    kdtree_workers: int = param(2, "threads of the nearest-neighbour queries (scipy cKDTree)")


@dataclass(frozen=True)
class GraphConfig:
    keyframe_dist_m: float = param(1.0, "new keyframe after this translation (surroundingkeyframeAddingDistThreshold)", "m")
    keyframe_angle_rad: float = param(0.2, "... or this rotation", "rad")
    prior_variances: tuple[float, float, float, float, float, float] = param(
        (1e-2, 1e-2, 3.141592653589793 ** 2, 1e8, 1e8, 1e8), "first-pose prior variances [rot, trans] (LIO-SAM)")
    odometry_variances: tuple[float, float, float, float, float, float] = param(
        (1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4), "odometry between-factor variances [rot, trans]")
    factorization: str = param("QR", "iSAM2 factorisation; gtsam 4.3's CHOLESKY rejects the loose prior")


@dataclass(frozen=True)
class LoopConfig:
    enabled: bool = param(True, "radius-search loop closure (loopClosureEnableFlag)")
    search_radius_m: float = param(15.0, "candidate keyframes within this (historyKeyframeSearchRadius)", "m")
    time_gap_s: float = param(30.0, "... and older than this (historyKeyframeSearchTimeDiff)", "s")
    neighbours: int = param(25, "submap of +/- this many keyframes (historyKeyframeSearchNum)")
    fitness_threshold_m2: float = param(0.3, "accept ICP if mean squared NN distance below (historyKeyframeFitnessScore)", "m^2")
    icp_max_correspondence_m: float = param(30.0, "ICP max correspondence distance (first stage)", "m")
    every_n_keyframes: int = param(1, "try a loop closure every n keyframes (LIO-SAM: a 1 Hz thread)")


@dataclass(frozen=True)
class GpsConfig:
    enabled: bool = param(True, "add GNSS factors when the log has GNSS")
    pose_cov_threshold_m2: float = param(25.0, "only when the x/y pose variance exceeds this (poseCovThreshold)", "m^2")
    gps_cov_threshold_m2: float = param(2.0, "drop fixes with a larger variance (gpsCovThreshold)", "m^2")
    min_spacing_m: float = param(5.0, "distance between GNSS factors", "m")
    max_time_diff_s: float = param(0.2, "fix must be this close to the keyframe", "s")


@dataclass(frozen=True)
class SlamConfig:
    method: str = param("lio", "SLAM method: lio (this project's LIO-SAM replay) or kiss-icp (peer)")
    use_loop_closure: bool = param(True, "enable radius-search loop closure")
    use_gps: bool = param(True, "add GNSS factors when the log has GNSS")
    mapping_interval_s: float = param(0.15, "process a sweep only if this much later than the last (mappingProcessInterval)", "s")
    deskew_translation: bool = param(True, "also remove the translation during the sweep (constant velocity); "
                                     "LIO-SAM deskews rotation only")
    gyro_bias_init_s: float = param(0.0, "average the gyro over the first seconds as its bias (0 = off)", "s")
    features: FeatureConfig = section(FeatureConfig, "range image and feature extraction")
    matching: MatchingConfig = section(MatchingConfig, "scan-to-map matching")
    graph: GraphConfig = section(GraphConfig, "keyframes and the factor graph")
    loop: LoopConfig = section(LoopConfig, "loop closure")
    gps: GpsConfig = section(GpsConfig, "GNSS factors")
