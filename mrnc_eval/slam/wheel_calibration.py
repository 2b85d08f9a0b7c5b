"""Online calibration of skid-steer wheel odometry against the gyro (and the LiDAR where it pins
the forward direction), with uncertainty, and a gate on each wheel increment.

Model, per bin of `bin_s` seconds (base_link, planar):
    wheel yaw rate  w_w = f * w_g + a * v_w + c        (f: effective track factor, the skid: wheel
                                                         yaw = f x true yaw; a = L/R mismatch / track,
                                                         1/m; c: yaw-rate offset, rad/s)
    wheel distance  d_w = (1 + s) * d_lidar             (s: scale error, on straight keyframe steps
                                                         where the LiDAR odometry is not degenerate)
w_g is the gyro's yaw rate about base_link z with the bias of the stationary start removed. The yaw
model is a recursive least-squares fit with a weak prior (f = 1, a = c = 0); its residual variance
gives the uncertainty. A bin whose innovation (w_w minus the prediction from the estimates before it)
fails a chi-square test (1 dof) is rejected: it does not update the fit and its yaw comes from the gyro.
The calibrated yaw rate of a bin is (w_w - a v_w - c) / f, its distance d_w / (1 + s).

The scale is a robust fit over the distance steps so far (`fit_scale`): tracks that slip on soft or
wet ground over-read on the steps crossing it (the yard circle's wet patch: +17-19 %) and not
elsewhere, while a rolling-radius error is in every step. A step whose wheel-minus-LiDAR residual
fails the chi-square test (1 dof) against the fit of the others is counted as slip and left out;
the sigma is inflated by the scatter of the steps kept when it exceeds the configured one."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.data import ImuSeries
from mrnc_eval.geometry import rotation
from mrnc_eval.slam.config import WheelCalibrationConfig
from mrnc_eval.slam.wheel_odometry import WheelTrack


@dataclass(frozen=True, kw_only=True)
class WheelIncrements:
    """The wheel track as per-sample increments in base_link: forward distance (m), yaw (rad)."""

    stamps: np.ndarray  # (N,) s, sample times; increment i is from stamps[i] to stamps[i + 1]
    forward_m: np.ndarray  # (N - 1,)
    lateral_m: np.ndarray  # (N - 1,)
    yaw_rad: np.ndarray  # (N - 1,)
    start: np.ndarray  # 4x4 first pose (odom frame)

    @classmethod
    def of(cls, track: WheelTrack) -> WheelIncrements:
        yaw = np.unwrap(rotation.rpy(rotation.quat_to_matrix(track.quat_xyzw))[:, 2])
        d = np.diff(track.positions[:, :2], axis=0)
        c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
        fwd, lat = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
        start = np.eye(4)
        start[:3, :3] = rotation.yaw_matrix(yaw[0])
        start[:3, 3] = track.positions[0]
        return cls(stamps=np.asarray(track.stamps, float), forward_m=fwd, lateral_m=lat, yaw_rad=np.diff(yaw),
                   start=start)


def integrate(inc: WheelIncrements, forward_m: np.ndarray, yaw_rad: np.ndarray) -> WheelTrack:
    """Dead-reckon increments (midpoint heading) into a planar odom -> base_link track."""
    yaw0 = float(rotation.rpy(inc.start[:3, :3])[2])
    yaw = yaw0 + np.r_[0.0, np.cumsum(yaw_rad)]
    mid = yaw[:-1] + 0.5 * yaw_rad
    dx = forward_m * np.cos(mid) - inc.lateral_m * np.sin(mid)
    dy = forward_m * np.sin(mid) + inc.lateral_m * np.cos(mid)
    pos = np.c_[inc.start[0, 3] + np.r_[0.0, np.cumsum(dx)], inc.start[1, 3] + np.r_[0.0, np.cumsum(dy)],
                np.full(yaw.size, inc.start[2, 3])]
    return WheelTrack(stamps=inc.stamps, positions=pos, quat_xyzw=rotation.matrix_to_quat(rotation.yaw_matrix(yaw)))


def track_from_twist(stamps: np.ndarray, v_mps: np.ndarray, yaw_rate_rad_s: np.ndarray) -> WheelTrack:
    """Dead-reckon an odometry's body twist (forward speed m/s, yaw rate rad/s at `stamps`, s; mean of
    neighbouring samples over each step) into a planar odom -> base_link track from the identity."""
    dt = np.diff(np.asarray(stamps, float))
    fwd = 0.5 * (v_mps[1:] + v_mps[:-1]) * dt
    inc = WheelIncrements(stamps=np.asarray(stamps, float), forward_m=fwd, lateral_m=np.zeros(fwd.size),
                          yaw_rad=0.5 * (yaw_rate_rad_s[1:] + yaw_rate_rad_s[:-1]) * dt, start=np.eye(4))
    return integrate(inc, inc.forward_m, inc.yaw_rad)


def gyro_yaw_rate(imu: ImuSeries, imu_in_base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, yaw rate about base_link z, rad/s) from the IMU's gyro and its rotation in base_link."""
    return np.asarray(imu.stamps, float), np.asarray(imu.gyro @ imu_in_base[:3, :3].T, float)[:, 2]


def stationary_gyro_bias(stamps: np.ndarray, yaw_rate: np.ndarray, inc: WheelIncrements,
                         max_speed_mps: float, window_s: float = 0.2) -> float | None:
    """Mean gyro yaw rate while the wheels say the machine stands: from the log's start until the
    wheel speed averaged over window_s (the pickups' noise averaged down) first exceeds
    max_speed_mps, less one window; None without such a stretch of >= 5 gyro samples."""
    if inc.stamps.size < 3:
        return None
    dist = np.r_[0.0, np.cumsum(inc.forward_m)]
    ahead = np.searchsorted(inc.stamps, inc.stamps + window_s).clip(max=inc.stamps.size - 1)
    span = np.maximum(inc.stamps[ahead] - inc.stamps, 1e-6)
    speed = np.abs(dist[ahead] - dist) / span
    moving = np.flatnonzero((speed > max_speed_mps) & (inc.stamps[ahead] > inc.stamps))
    t_move = inc.stamps[moving[0]] if moving.size else inc.stamps[-1]
    still = (stamps >= inc.stamps[0]) & (stamps < t_move)
    return float(yaw_rate[still].mean()) if still.sum() >= 5 else None


def straight_gyro_bias(stamps: np.ndarray, yaw_rate: np.ndarray, inc: WheelIncrements, t: float,
                       cfg: WheelCalibrationConfig) -> tuple[float, float] | None:
    """(bias, 1 sigma), rad/s: the gyro's mean yaw rate over [t - straight_bias_window_s, t] when the
    machine drove straight through it, else None. Straight: in each 1 s sub-bin the wheels drove at
    least straight_min_speed_mps and turned by at most 2.5 x straight_max_yaw_rate_rad_s, over the
    window by at most straight_max_yaw_rate_rad_s (the raw wheels: an L/R mismatch turns them on a
    straight), and the sub-bins' gyro means lie within straight_max_gyro_spread_rad_s. On a loop or
    circle the mean gyro is the turn rate, not the bias: the wheels' turn fails the guard there
    (matrix loops begun mid-drive, seeds 0-4: no stretch taken); a gentle arc under the limits
    passes, which straight_bias_sigma_rad_s allows for."""
    window = cfg.straight_bias_window_s
    n = int(round(window))
    if n < 2 or inc.stamps.size < 3 or t - window < inc.stamps[0] or t > inc.stamps[-1]:
        return None
    edges = t - window + np.linspace(0.0, window, n + 1)
    i, j = np.searchsorted(inc.stamps, edges), np.searchsorted(stamps, edges)
    if np.any(np.diff(j) == 0) or np.any(np.diff(i) == 0):
        return None
    span = window / n
    dist = np.add.reduceat(inc.forward_m[:i[-1]], i[:-1]) / span  # only what arrived by t
    turn = np.add.reduceat(inc.yaw_rad[:i[-1]], i[:-1]) / span
    gyro = np.add.reduceat(yaw_rate[:j[-1]], j[:-1]) / np.diff(j)
    if dist.min() < cfg.straight_min_speed_mps or abs(turn.mean()) > cfg.straight_max_yaw_rate_rad_s \
            or np.abs(turn).max() > 2.5 * cfg.straight_max_yaw_rate_rad_s \
            or np.ptp(gyro) > cfg.straight_max_gyro_spread_rad_s:
        return None
    return float(gyro.mean()), float(np.hypot(cfg.straight_bias_sigma_rad_s, gyro.std() / np.sqrt(n)))


@dataclass(kw_only=True)
class WheelCalibrator:
    """Causal estimator: `update(t)` consumes the bins that ended by t; `track()` is the wheel track
    re-integrated with the current estimates (rejected bins take the gyro's yaw)."""

    cfg: WheelCalibrationConfig
    inc: WheelIncrements
    gyro_t: np.ndarray
    gyro_w: np.ndarray
    gyro_bias: float
    track_width_m: float
    # yaw model [f, a, c]: information matrix and vector (prior included)
    info: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    vec: np.ndarray = field(default_factory=lambda: np.zeros(3))
    theta: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    # scale: the distance steps (wheel m, LiDAR m) and the robust fit of them
    steps_wheel_m: list[float] = field(default_factory=list)
    steps_lidar_m: list[float] = field(default_factory=list)
    scale_fit: ScaleFit | None = None
    next_bin: int = 0
    n_bins: int = 0
    n_rejected: int = 0
    raw_res: list[float] = field(default_factory=list)  # w_w - w_g per accepted bin (uncalibrated)
    res: list[float] = field(default_factory=list)  # innovation per bin (before its update), rad/s
    nis: list[float] = field(default_factory=list)  # normalised innovation squared per bin
    rejected_bins: list[int] = field(default_factory=list)
    bins: tuple[np.ndarray, np.ndarray] = (np.zeros(0, int), np.zeros(0, int))
    bin_yaw_gyro: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bin_span: np.ndarray = field(default_factory=lambda: np.zeros(0))  # each bin's duration, s
    inc_yaw_gyro: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the gyro's yaw over each increment
    # (bias of the standing start removed), rad: the blend of the increments no bin has consumed yet
    sigma2: float = 0.0  # running residual variance, (rad/s)^2
    standing_start: bool = False  # the gyro bias was measured over a standing start
    gyro_bias_source: str = "none"  # "standing start", "straight drive" (late, set_gyro_bias) or "none"
    gyro_bias_sigma: float = 0.0  # 1 sigma of a late bias, rad/s (the standing start's counts as exact)
    gyro_bias_t: float | None = None  # when a late bias arrived (log time), s
    next_bias_try: float = -np.inf  # log time of the next straight-stretch check, s

    @classmethod
    def build(cls, track: WheelTrack, imu: ImuSeries | None, imu_in_base: np.ndarray | None,
              cfg: WheelCalibrationConfig) -> WheelCalibrator | None:
        if imu is None or imu_in_base is None or track.stamps.size < 3 or imu.stamps.size < 10:
            return None
        inc = WheelIncrements.of(track)
        gt, gw = gyro_yaw_rate(imu, imu_in_base)
        if np.any(np.diff(gt) < 0):  # the reader sorts its streams; a hand-made series may not be
            order = np.argsort(gt, kind="stable")
            gt, gw = gt[order], gw[order]
        bias = stationary_gyro_bias(gt, gw, inc, cfg.stationary_speed_mps)
        cal = cls(cfg=cfg, inc=inc, gyro_t=gt, gyro_w=gw, gyro_bias=0.0 if bias is None else bias,
                  track_width_m=cfg.track_width_m)
        cal.standing_start = bias is not None
        cal.gyro_bias_source = "standing start" if bias is not None else "none"
        cal.info = np.diag(1.0 / np.square(cfg.prior_sigmas))
        cal.vec = cal.info @ np.array([1.0, 0.0, 0.0])
        cal.sigma2 = cfg.yaw_rate_sigma_rad_s ** 2
        cal.scale_fit = fit_scale(np.zeros(0), np.zeros(0), cfg)
        cal.bins = _bins(inc.stamps, cfg.bin_s)
        cal.bin_yaw_gyro = np.zeros(cal.bins[0].size)
        dt = np.diff(inc.stamps)
        cal.bin_span = np.array([max(dt[a:b].sum(), 1e-9) for a, b in zip(*cal.bins, strict=True)])
        cal.inc_yaw_gyro = _gyro_increments(gt, gw - cal.gyro_bias, inc.stamps)
        return cal

    # ---- estimates
    @property
    def track_factor(self) -> float:
        return float(self.theta[0])

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of [f, a, c]: the information's inverse, scaled up when the measured residual
        variance exceeds the configured one."""
        inflate = max(1.0, self.sigma2 / self.cfg.yaw_rate_sigma_rad_s ** 2)
        return np.asarray(np.linalg.inv(self.info) * inflate, float)

    @property
    def scale(self) -> float:
        """1 + s: wheel distance / true distance."""
        return self.scale_fit.scale if self.scale_fit is not None else 1.0

    def lr_mismatch(self) -> tuple[float, float]:
        """Right-minus-left radius mismatch (fraction) and its sigma: a x track width."""
        return float(self.theta[1] * self.track_width_m), float(np.sqrt(self.covariance[1, 1]) * self.track_width_m)

    @property
    def bias_known(self) -> bool:
        """The gyro's bias was measured: over a standing start, or late (set_gyro_bias)."""
        return self.standing_start or self.gyro_bias_t is not None

    def update(self, t: float) -> None:
        """Consume the bins that end at or before t (after a late gyro bias, when one is due)."""
        self._try_late_bias(t)
        starts, ends = self.bins
        while self.next_bin < starts.size and self.inc.stamps[ends[self.next_bin]] <= t:
            self._update_bin(self.next_bin)
            self.next_bin += 1

    def _try_late_bias(self, t: float) -> None:
        """Without a standing start, once a second: the gyro's mean over the last straight_bias_window_s
        when the machine drove straight through it (straight_gyro_bias) is taken as its bias."""
        cfg = self.cfg
        if self.bias_known or cfg.straight_bias_window_s <= 0 or t < self.next_bias_try:
            return
        self.next_bias_try = t + 1.0
        found = straight_gyro_bias(self.gyro_t, self.gyro_w, self.inc, t, cfg)
        if found is not None:
            self.set_gyro_bias(found[0], found[1], t)

    def set_gyro_bias(self, bias: float, sigma: float, t: float, source: str = "straight drive") -> None:
        """A gyro bias (rad/s, 1 sigma) measured late, at log time t: the yaw fit starts again from its
        prior over the bins consumed so far with the gyro less this bias (the same data, known by t),
        the gyro's increments follow, and from now on the gyro is blended (its sigma with the bias's)
        and the fitted offset c kept, as after a standing start."""
        self.gyro_bias, self.gyro_bias_sigma, self.gyro_bias_t, self.gyro_bias_source = bias, sigma, t, source
        self.inc_yaw_gyro = _gyro_increments(self.gyro_t, self.gyro_w - self.gyro_bias, self.inc.stamps)
        self.info = np.diag(1.0 / np.square(self.cfg.prior_sigmas))
        self.vec = self.info @ np.array([1.0, 0.0, 0.0])
        self.theta = np.array([1.0, 0.0, 0.0])
        self.sigma2 = self.cfg.yaw_rate_sigma_rad_s ** 2
        self.n_bins = self.n_rejected = 0
        for name in ("raw_res", "res", "nis", "rejected_bins"):
            getattr(self, name).clear()
        for k in range(self.next_bin):
            self._update_bin(k)

    def _update_bin(self, k: int) -> None:
        i0, i1 = self.bins[0][k], self.bins[1][k]
        t0, t1 = self.inc.stamps[i0], self.inc.stamps[i1]
        dt = t1 - t0
        if dt <= 0:
            return
        i, j = np.searchsorted(self.gyro_t, [t0, t1])  # the gyro samples in [t0, t1): stamps sorted (build)
        if i == j:
            return
        wg = float(self.gyro_w[i:j].mean()) - self.gyro_bias
        self.bin_yaw_gyro[k] = wg * dt
        ww = float(self.inc.yaw_rad[i0:i1].sum()) / dt
        v = float(self.inc.forward_m[i0:i1].sum()) / dt
        x = np.array([wg, v, 1.0])
        self.n_bins += 1
        e = ww - float(x @ self.theta)
        s = self.sigma2 + float(x @ self.covariance @ x)
        nis = e * e / s
        self.res.append(e)
        self.nis.append(nis)
        if nis > self.cfg.gate_chi2 and self.n_bins > self.cfg.warmup_bins:
            self.n_rejected += 1
            self.rejected_bins.append(k)
            return
        self.raw_res.append(ww - wg)
        w = 1.0 / self.cfg.yaw_rate_sigma_rad_s ** 2
        self.info += w * np.outer(x, x)
        self.vec += w * x * ww
        self.theta = np.linalg.solve(self.info, self.vec)
        # residual variance: exponential average of accepted innovations, floored at the configured sigma
        self.sigma2 = max(0.95 * self.sigma2 + 0.05 * e * e, (0.1 * self.cfg.yaw_rate_sigma_rad_s) ** 2)

    def restamp_gyro(self, shift_s: float) -> None:
        """The IMU stamps moved by -shift_s (the replay applied an IMU-LiDAR offset estimate): the gyro
        blended into the increments no bin has consumed yet follows, or a lagging gyro's timing would
        enter the sweep guesses and, through the matched poses, the next offset estimate."""
        self.gyro_t = self.gyro_t - shift_s
        self.inc_yaw_gyro = _gyro_increments(self.gyro_t, self.gyro_w - self.gyro_bias, self.inc.stamps)

    def add_distance(self, wheel_m: float, lidar_m: float) -> None:
        """A stretch where the LiDAR odometry pinned the forward direction: wheel vs LiDAR distance."""
        if lidar_m < self.cfg.scale_min_distance_m:
            return
        self.steps_wheel_m.append(wheel_m)
        self.steps_lidar_m.append(lidar_m)
        self.scale_fit = fit_scale(np.asarray(self.steps_wheel_m), np.asarray(self.steps_lidar_m), self.cfg)

    def track(self) -> WheelTrack:
        """The wheel track with the current calibration. Each consumed bin's yaw is the
        inverse-variance mean of the calibrated wheels' yaw and the gyro's (its bias measured over the
        standing start; without one the wheels' alone), with the measured residual variance for the
        wheels and gyro_yaw_rate_sigma_rad_s for the gyro: noisy speed pickups random-walk the wheel
        heading, exact ones keep it. The increments after the last consumed bin take the same blend.
        (The fitted offset c is not added to the gyro: on a straight
        drive it trades off against the L/R term.) Rejected bins take the gyro's yaw. Without a
        standing start c is left out: the gyro's bias is then unmeasured and c soaks it up (c = -f x
        bias; open loop begun mid-drive, tuning seeds: c -1.5..-15.8 mrad/s, against -0.5..+1.8 with
        the standing start), which the wheels' yaw would carry (end yaw 1.3-4.1 deg, 0.5-1.0 without)."""
        _, a, c = self.theta
        c = c if self.bias_known else 0.0  # no wheel phenomenon: a yaw-rate offset is the gyro's bias
        f = self._track_factor_used()
        dt = np.diff(self.inc.stamps)
        fwd = self.inc.forward_m / self.scale
        yaw = (self.inc.yaw_rad - a * self.inc.forward_m - c * dt) / f
        w_gyro = self.gyro_weight()
        n = self.next_bin
        # the increments after the last consumed bin (the current sweep's): the same blend, increment by
        # increment, ungated (their bin is not complete); without it a sweep's wheel guess took the
        # wheels' yaw alone there: 0.05 m/s pickup noise is +-0.5 deg per 0.2 s, the gyro's 0.02 deg
        tail = int(self.bins[1][n - 1]) if n else 0
        yaw[tail:] = (1.0 - w_gyro) * yaw[tail:] + w_gyro * self.inc_yaw_gyro[tail:]
        if n:  # the consumed bins cover dt[bins[0][0]:bins[1][n - 1]] contiguously (_bins)
            idx = np.arange(self.bins[0][0], self.bins[1][n - 1])
            bin_of = np.repeat(np.arange(n), self.bins[1][:n] - self.bins[0][:n])
            gyro = self.bin_yaw_gyro[bin_of] * dt[idx] / self.bin_span[bin_of]
            weight = np.full(n, w_gyro)
            weight[self.rejected_bins] = 1.0
            w = weight[bin_of]
            yaw[idx] = (1.0 - w) * yaw[idx] + w * gyro
        return integrate(self.inc, fwd, yaw)

    def _track_factor_used(self) -> float:
        """The fitted track factor, or 1 while the fit is implausible (|f| <= 0.2)."""
        f = float(self.theta[0])
        return f if abs(f) > 0.2 else 1.0

    def gyro_weight(self) -> float:
        """The gyro's weight in a consumed bin's yaw (and the increments after the last): the inverse-
        variance share against the calibrated wheels' (their variance the measured residual one over
        f^2; the configured one until the fit has its own). 0 without a standing start (the gyro's bias
        unmeasured) or with gyro_yaw_rate_sigma_rad_s = 0. From the first bin: the warm-up's raw wheel
        yaw was 0.7 of 2.5 deg of the open line's final heading error (tuning seed 6). It carries a
        lagging IMU's timing into the online poses (the online offset estimate's 30 ms read 27.9 ms in
        two passes), not into the default re-matched estimate (calibrated wheels, yard and forest seeds
        3-5: 17 of 18 within 2 ms, 14 without)."""
        if self.cfg.gyro_yaw_rate_sigma_rad_s <= 0 or not self.bias_known:
            return 0.0
        var_w = self._wheel_yaw_rate_var()
        return float(var_w / (var_w + self._gyro_var()))

    def _gyro_var(self) -> float:
        """Variance of the gyro's bin yaw rate, (rad/s)^2: the configured one, plus a late bias's."""
        return self.cfg.gyro_yaw_rate_sigma_rad_s ** 2 + self.gyro_bias_sigma ** 2

    def _wheel_yaw_rate_var(self) -> float:
        """Variance of the calibrated wheels' yaw rate, (rad/s)^2: sigma2 is measured on the raw wheel
        yaw rate (the model's f x gyro + a v + c), and track() divides the wheels' yaw by f."""
        return max(self.sigma2, 1e-12) / self._track_factor_used() ** 2

    def yaw_quality(self) -> float:
        """Weight (0-1] for the yaw hold: the reference yaw-rate sigma over the sigma of the guess's
        yaw rate, squared (an information ratio). The guess's yaw is `track()`'s: with the gyro blended
        in, the blend's variance (w^2 gyro + (1 - w)^2 wheels: at most the gyro's, so the full hold with
        the defaults); without (w = 0), the calibrated wheels' (the measured residual variance over f^2,
        as the blend's wheel term: continuous in w). Held by the wheels' residual alone, the open line's
        guess (97 % gyro) let scan-to-map's yaw steps through (0.05-0.15 deg a sweep, +1.8 deg over
        40 s on tuning seed 6, where the gyro alone stayed within 0.2 deg)."""
        if self.n_bins < self.cfg.warmup_bins:
            return 1.0
        w = self.gyro_weight()
        var = w ** 2 * self._gyro_var() + (1.0 - w) ** 2 * self._wheel_yaw_rate_var()
        ratio = self.cfg.yaw_rate_sigma_rad_s ** 2 / var
        return float(np.clip(ratio, self.cfg.min_yaw_quality, 1.0))


@dataclass(frozen=True, kw_only=True)
class ScaleFit:
    """The scale fit over the distance steps: 1 + s, its 1-sigma, the steps kept and those put down
    to slip (with their mean wheel over-read, a fraction of the LiDAR distance)."""

    scale: float
    sigma: float
    steps: int = 0
    slip_steps: int = 0
    slip_mean: float | None = None


def fit_scale(wheel_m: np.ndarray, lidar_m: np.ndarray, cfg: WheelCalibrationConfig) -> ScaleFit:
    """Robust fit of wheel = (1 + s) lidar over the steps, with the prior 1 + s = 1 +- scale_prior_sigma.
    Start at the steps' median ratio (weighted by distance squared, the least-squares weights), then
    alternate: keep the steps whose residual passes the chi-square test (scale_gate_chi2, 1 dof)
    against the step's sigma (scale_distance_sigma_m) and the fit's, and refit on them. Slip is the
    minority explanation: unless at least two steps agree and carry more than half the weight, the
    steps cannot tell slip from scale, and all are kept. The sigma is the least-squares one times
    sqrt(chi-square / dof) of the kept steps when that exceeds 1: slip below the gate, or steps
    noisier than configured, widen it instead of passing as a scale."""
    if wheel_m.size == 0:
        return ScaleFit(scale=1.0, sigma=cfg.scale_prior_sigma)
    weight = lidar_m ** 2
    scale, var_s = _weighted_median(wheel_m / lidar_m, weight), 0.0
    keep = np.ones(wheel_m.size, bool)
    for _ in range(10):
        res = wheel_m - scale * lidar_m
        new = res ** 2 <= cfg.scale_gate_chi2 * (cfg.scale_distance_sigma_m ** 2 + weight * var_s)
        if new.sum() < 2 or weight[new].sum() <= 0.5 * weight.sum():
            new = np.ones(wheel_m.size, bool)
        scale, var_s = _scale_lsq(wheel_m[new], lidar_m[new], cfg)
        if np.array_equal(new, keep):
            break
        keep = new
    res = wheel_m - scale * lidar_m
    dof = int(keep.sum()) - 1
    chi2 = float(np.sum(res[keep] ** 2)) / cfg.scale_distance_sigma_m ** 2
    inflate = max(1.0, chi2 / dof) if dof > 0 else 1.0
    slip = ~keep
    return ScaleFit(scale=scale, sigma=float(np.sqrt(var_s * inflate)), steps=int(keep.sum()),
                    slip_steps=int(slip.sum()),
                    slip_mean=float(np.mean(res[slip] / lidar_m[slip])) if slip.any() else None)


def _scale_lsq(wheel_m: np.ndarray, lidar_m: np.ndarray, cfg: WheelCalibrationConfig) -> tuple[float, float]:
    """Least-squares 1 + s and its variance from the steps and the prior (1 +- scale_prior_sigma)."""
    var_d, info0 = cfg.scale_distance_sigma_m ** 2, 1.0 / cfg.scale_prior_sigma ** 2
    info = info0 + float(np.sum(lidar_m ** 2)) / var_d
    return (info0 + float(np.sum(lidar_m * wheel_m)) / var_d) / info, 1.0 / info


def _gyro_increments(stamps: np.ndarray, rate: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The yaw (rad) the yaw rate `rate` (rad/s, at `stamps`, sorted) turns over each interval of `at`
    (trapezoids, the rate held at the ends outside its span)."""
    if stamps.size < 2:
        return np.zeros(max(at.size - 1, 0))
    angle = np.r_[0.0, np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(stamps))]
    inside = np.interp(at, stamps, angle)
    inside += (at - np.clip(at, stamps[0], stamps[-1])) * np.where(at < stamps[0], rate[0], rate[-1])
    return np.asarray(np.diff(inside), float)


def _weighted_median(x: np.ndarray, w: np.ndarray) -> float:
    order = np.argsort(x)
    cum = np.cumsum(w[order])
    return float(x[order][np.searchsorted(cum, 0.5 * cum[-1])])


def _bins(stamps: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Index ranges [start, end) of increments in consecutive bins of ~bin_s seconds."""
    if stamps.size < 2:
        return np.zeros(0, int), np.zeros(0, int)
    edges = np.searchsorted(stamps, np.arange(stamps[0], stamps[-1], bin_s))
    edges = np.unique(np.r_[edges, stamps.size - 1])
    return edges[:-1], edges[1:]
