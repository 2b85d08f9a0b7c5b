"""A loosely coupled GNSS/INS inside graph #2 (the IMU preintegration graph): GNSS antenna positions
as factors on graph #2's pose keys (with the antenna lever arm), so the fixes steer the velocity and
the accelerometer biases the IMU dead-reckons with, not only graph #1's keyframes.

Why: on bare ground scan-to-map leaves x, y and yaw to the IMU (the ground holds z, roll and pitch
only), and graph #1 factors cannot reach graph #2's velocity; the chain is metres off before a
chain-vs-fixes alignment has travel enough (docs/simulation.md, issue 28).

The ENU -> map alignment comes from the fixes' own track, not from the drifting chain: a ground
vehicle drives along its forward axis, so the yaw is the fixes' course (the median direction of
pairs of fixes inside one multipath segment) minus the chain's median forward-axis heading over
the same stamps (the gyro's yaw, good to a degree over seconds while x, y drift by metres); the
translation puts
the fixes of the first `ins_origin_s` on the chain's antenna there (it has hardly drifted yet).
It is fixed once, when the fixes have travelled `ins_align_travel_m` (the course against the mean
heading on a near-straight stretch; on one that turns, pair by pair: a chord runs along the heading
at its middle), and never re-fitted, so it cannot slide the chain. Whatever the alignment got wrong
is rigid (a rotation and offset of the whole track). Before it, graph #2 runs as before (IMU dead reckoning).

Each fix is gated (GnssIns.judge): on its innovation against graph #2's own marginal covariance of
the antenna position plus the fix's variance (chi-square, 2 dof) and against the trend of the
recent innovations; a held multipath jump (a flat run of rejected fixes) is taken off the later
fixes as an offset; a factor has a Huber kernel. After `ins_reacquire_s` of rejections without a
break the fixes are taken again (the chain, not the fixes, has diverged). Once aligned, graph #2's
degenerate directions along yaw, x and y are left to the fixes, its accelerometer noise and bias
walk are raised to what the field IMU does, and its periodic restarts start from its marginals.

Measured (docs/simulation.md, "GNSS/INS in graph #2"): it holds a synthetic drive and the tuning
seeds of the open line without wheels near a metre, but diverges on the report seeds; off by default
(slam.gps.ins)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.slam.config import GpsConfig
from mrnc_eval.slam.imu import ImuOdometry
from mrnc_eval.slam.output import SlamEvent


@dataclass(frozen=True, kw_only=True)
class EnuAlignment:
    """ENU -> map: map_xy = rot @ enu_xy + t."""

    rot: np.ndarray  # (2, 2)
    t: np.ndarray  # (2,) m
    yaw_rad: float

    def to_map(self, enu_xy: np.ndarray) -> np.ndarray:
        return np.asarray(enu_xy @ self.rot.T + self.t, np.float64)


@dataclass(frozen=True, kw_only=True)
class FixUpdate:
    """One fix at a graph #2 key: the antenna position (map, m; z is the chain's own) it says the
    key has, and its sigmas (m)."""

    stamp: float
    position: np.ndarray  # (3,)
    sigmas: np.ndarray  # (3,)


def jump_segments(xy: np.ndarray, moved: np.ndarray, jump_m: float) -> np.ndarray:
    """Segment label per fix (n,): a new segment starts where the median of the next 3 fixes is further
    than jump_m plus the chain's own displacement `moved` (n, 2; any frame: only its length counts)
    from the median of the previous 3 (a multipath jump switching on or off)."""
    label = np.zeros(len(xy), int)
    k = 3
    while k <= len(xy) - 3:
        step = np.linalg.norm(np.median(xy[k:k + 3], axis=0) - np.median(xy[k - 3:k], axis=0))
        expected = np.linalg.norm(np.median(moved[k:k + 3], axis=0) - np.median(moved[k - 3:k], axis=0))
        if step > jump_m + expected:
            label[k:] += 1
            k += 3
        else:
            k += 1
    return label


def _pairs_within(t: np.ndarray, max_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs i < j of the sorted stamps t with t[j] - t[i] <= max_dt_s, in np.triu_indices'
    order: a band, not all n^2 pairs (minutes of fixes before the alignment is fixed)."""
    n = len(t)
    end = np.searchsorted(t, t + max_dt_s, side="right")  # one past each fix's last partner
    width = int((end - np.arange(n)).max(initial=1))
    i = np.concatenate([np.arange(n - k) for k in range(1, width)] or [np.zeros(0, int)])
    j = np.concatenate([np.arange(k, n) for k in range(1, width)] or [np.zeros(0, int)])
    keep = j < end[i]
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order]


def robust_course(t: np.ndarray, xy: np.ndarray, sigma_m: float, segment: np.ndarray | None = None,
                  max_dt_s: float = 3.0, min_pairs: int = 5) -> tuple[float, float, np.ndarray, float]:
    """Course (rad, ENU) and travel (m) of a stretch of fixes (stamps t, s; positions xy, m),
    robust to multipath jumps: the median direction of the pairs of fixes in the same `segment`
    (jump_segments), at most max_dt_s apart and at least 5 sigma (1.5 m at least) apart in space. A
    jump that holds for seconds shifts the fixes during it by one offset, which cancels in a pair
    inside it. Travel: between the medians of the first and last fifth. The inlier mask: the fixes
    in at least one pair within 30 deg of the course. Spread: the pairs' median absolute deviation
    from the course (rad); fewer than min_pairs pairs: no course (pi)."""
    n = max(3, len(xy) // 5)
    travel = float(np.linalg.norm(np.median(xy[-n:], axis=0) - np.median(xy[:n], axis=0)))
    i, j = course_pairs(t, xy, sigma_m, segment, max_dt_s)
    if i.size < max(min_pairs, 5):
        return 0.0, 0.0, np.ones(len(xy), bool), float(np.pi)
    d = xy[j] - xy[i]
    ang = np.arctan2(d[:, 1], d[:, 0])
    course = circular_median(ang)
    near = np.abs(_wrap(ang - course)) <= np.radians(30.0)
    inl = np.zeros(len(xy), bool)
    inl[i[near]] = inl[j[near]] = True
    return course, travel, inl, float(np.median(np.abs(_wrap(ang - course))))


def course_pairs(t: np.ndarray, xy: np.ndarray, sigma_m: float, segment: np.ndarray | None,
                 max_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of fixes (i, j) a course is read from: at most max_dt_s apart in time, at least 5
    sigma (1.5 m at least) apart in space, inside one multipath `segment` (None: one segment)."""
    i, j = _pairs_within(t, max_dt_s)
    use = np.linalg.norm(xy[j] - xy[i], axis=1) >= max(5.0 * sigma_m, 1.5)
    if segment is not None:
        use &= segment[i] == segment[j]
    return i[use], j[use]


def heading_offset_turning(t: np.ndarray, xy: np.ndarray, segment: np.ndarray, sigma_m: float, *,
                           heading: np.ndarray, moved: np.ndarray, min_pairs: int,
                           max_dt_s: float = 3.0) -> tuple[float, float]:
    """Chain heading minus the fixes' course (rad) on a stretch that turns, and its spread (the median
    absolute deviation, rad; pi with fewer than min_pairs pairs). On an arc of constant curvature a
    pair's chord runs along the heading at the pair's middle, so each pair of `course_pairs` gives its
    own offset (`heading`: the chain's unwrapped forward-axis heading at each fix, rad); their median.
    Reversing: most pairs' chain displacement `moved` (n, 2, m) on their backward axis (drove_backwards)."""
    i, j = course_pairs(t, xy, sigma_m, segment, max_dt_s)
    if i.size < max(min_pairs, 5):
        return 0.0, float(np.pi)
    d = xy[j] - xy[i]
    mid = 0.5 * (heading[i] + heading[j])  # the heading at the pair's middle, fixes at a steady rate
    offset = _wrap(mid - np.arctan2(d[:, 1], d[:, 0]))
    back = backwards_each(moved[j] - moved[i], mid, np.linalg.norm(d, axis=1))
    if 2 * int(back.sum()) > back.size:
        offset = _wrap(offset + np.pi)
    yaw = circular_median(offset)
    return yaw, float(np.median(np.abs(_wrap(offset - yaw))))


def circular_median(angles: np.ndarray) -> float:
    """The median of angles (rad) about their circular mean (robust to a minority of outliers); within
    pi of the mean, not wrapped."""
    ref = np.arctan2(np.sin(angles).mean(), np.cos(angles).mean())
    return float(ref + np.median(_wrap(angles - ref)))


def _wrap(a: np.ndarray | float) -> np.ndarray:
    """Angles (rad) into (-pi, pi]."""
    return np.asarray(np.angle(np.exp(1j * np.asarray(a))), np.float64)


def robust_line(dt: np.ndarray, values: np.ndarray, sigma_m: float) -> np.ndarray:
    """The value (2,) at dt = 0 of a line per axis through values (n, 2) against dt (n,) s, re-fitted
    twice without the points further than 3 sigma + 0.3 m off it (multipath jumps)."""
    keep = np.ones(dt.size, bool)
    coef = np.zeros((2, 2))
    for _ in range(3):
        x = np.c_[np.ones(int(keep.sum())), dt[keep]]
        coef = np.linalg.lstsq(x, values[keep], rcond=None)[0]
        off = np.linalg.norm(values - (coef[0] + np.outer(dt, coef[1])), axis=1)
        new = off <= 3.0 * sigma_m + 0.3
        if new.sum() < 5 or np.array_equal(new, keep):
            break
        keep = new
    return np.asarray(coef[0], np.float64)


JUMP_SIGMAS = 2.5  # a multipath segment starts at a step of at least this many fix sigmas (float: ins_jump_m)
PAIR_WINDOW_S = 3.0  # a course's pairs of fixes are at most this far apart in time (s) ...
PAIR_WINDOW_S_PER_M = 10.0  # ... or this many seconds per metre of the fixes' sigma (single point, 1.5 m: 15 s)
TURNING_SPREAD_DEG = 15.0  # a turning stretch's pair offsets spread (median absolute deviation) at most this
REVERSE_MAX_ANGLE_DEG = 30.0  # the chain's displacement this close to its backward axis means reversing
REVERSE_MIN_FRACTION = 0.5  # ... and at least this fraction of the fixes' travel (dead reckoning is metres off)


def drove_backwards(moved: np.ndarray, heading: float, travel: float) -> bool:
    """Whether the chain's own displacement (2,) m over the alignment's stretch says the vehicle reversed
    along its forward axis (heading, rad). Before the alignment the chain is IMU dead reckoning without
    wheels, its direction 60-120 deg off the truth on some logs (open line seeds 3 / 4): only a
    displacement near the backward axis and comparable to the fixes' travel (m) counts; a ground
    vehicle otherwise drives forward (a sideways-drifting chain flipped seed 3's alignment by 180 deg)."""
    return bool(backwards_each(np.reshape(moved, (1, 2)), np.array([heading]), np.array([travel]))[0])


def backwards_each(moved: np.ndarray, heading: np.ndarray, travel: np.ndarray) -> np.ndarray:
    """drove_backwards for n stretches at once: displacements (n, 2) m, headings (n,) rad, travels (n,) m."""
    length = np.linalg.norm(moved, axis=1)
    along = moved[:, 0] * np.cos(heading) + moved[:, 1] * np.sin(heading)
    return np.asarray((length >= np.maximum(1.0, REVERSE_MIN_FRACTION * travel))
                      & (along < -np.cos(np.radians(REVERSE_MAX_ANGLE_DEG)) * length))


def gate_fix(innovation: np.ndarray, chain_cov: np.ndarray, fix_var: np.ndarray, chi2: float) -> tuple[bool, float]:
    """Whether a fix's horizontal innovation (2,) is consistent with the chain's position covariance
    (2, 2) plus the fix's variances (2,): Mahalanobis distance^2 against chi2. Returns (ok, d2)."""
    s = chain_cov + np.diag(fix_var)
    d2 = float(innovation @ np.linalg.solve(s, innovation))
    return d2 <= chi2, d2


@dataclass(kw_only=True)
class GnssIns:
    """The GNSS side of the GNSS/INS: alignment from the fixes' track, fixes as factors for graph #2."""

    gnss: GnssSeries
    cfg: GpsConfig
    forward_in_lidar: np.ndarray  # (3,) the vehicle's forward axis in the LiDAR frame
    antenna_in_lidar: np.ndarray  # (3,) m
    max_var_m2: float | None = None  # fixes with a larger horizontal variance are not used (None: gps_cov_threshold_m2)
    alignment: EnuAlignment | None = None
    usable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    next_fix: int = 0  # the first fix not consumed yet
    chain_t: list[float] = field(default_factory=list)
    chain_heading: list[float] = field(default_factory=list)  # yaw of the forward axis in the map, rad
    chain_antenna: list[np.ndarray] = field(default_factory=list)  # (3,) map
    rejected_since: float | None = None  # stamp of the first fix of the current run of rejections
    reacquiring: bool = False
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))  # multipath offset taken off the fixes, m
    pending: list[np.ndarray] = field(default_factory=list)  # rejected fixes' innovations less the trend, m
    pending_t: list[float] = field(default_factory=list)  # ... their stamps, s
    steps: int = 0
    history: list[tuple[float, np.ndarray]] = field(default_factory=list)  # accepted: (stamp, innovation (2,) m)
    accepted: int = 0
    rejected: int = 0

    def __post_init__(self) -> None:
        var = np.diagonal(self.gnss.covariance, axis1=1, axis2=2)
        limit = self.cfg.gps_cov_threshold_m2 if self.max_var_m2 is None else self.max_var_m2
        self.usable = np.all(var[:, :2] <= limit, axis=1) & \
            np.all(np.isfinite(self.gnss.enu), axis=1) & np.all(np.isfinite(var[:, :2]), axis=1)

    def observe(self, t: float, lidar_pose: np.ndarray) -> None:
        """The chain's pose at a mapped sweep, for the alignment."""
        fwd = lidar_pose[:3, :3] @ self.forward_in_lidar
        self.chain_t.append(t)
        self.chain_heading.append(float(np.arctan2(fwd[1], fwd[0])))
        self.chain_antenna.append(lidar_pose[:3, :3] @ self.antenna_in_lidar + lidar_pose[:3, 3])

    def try_align(self, t: float) -> EnuAlignment | None:
        """Fix the alignment once the fixes since the first sweep have travelled far enough on a
        near-straight stretch; returns it when it was fixed now."""
        if self.alignment is not None:
            return None
        self.alignment = self.fit_alignment(t, self.cfg.ins_align_travel_m)
        if self.alignment is not None:
            self.next_fix = int(np.searchsorted(self.gnss.stamps, t, side="right"))  # from now on
        return self.alignment

    def fit_alignment(self, t: float, travel_m: float, max_spread_deg: float = 180.0,
                      min_pairs: int = 5) -> EnuAlignment | None:
        """The ENU -> map alignment from the fixes up to t once they have travelled travel_m (m) on a
        near-straight stretch and the course has at least min_pairs pairs spread by at most
        max_spread_deg (median absolute deviation), else None; nothing is stored."""
        if len(self.chain_t) < 2:
            return None
        c = self.cfg
        sel = self.usable & (self.gnss.stamps >= self.chain_t[0]) & (self.gnss.stamps <= t)
        if sel.sum() < 10:
            return None
        stamps, enu = self.gnss.stamps[sel], self.gnss.enu[sel, :2]
        sigma = float(np.sqrt(np.median(np.diagonal(self.gnss.covariance[sel], axis1=1, axis2=2)[:, :2])))
        ant = np.asarray(self.chain_antenna)
        moved = np.column_stack([np.interp(stamps, self.chain_t, ant[:, i]) for i in range(2)])
        segments = jump_segments(enu, moved, max(c.ins_jump_m, JUMP_SIGMAS * sigma))
        window = max(PAIR_WINDOW_S, PAIR_WINDOW_S_PER_M * sigma)  # pairs 5 sigma apart need time to get there
        course, travel, inl, spread = robust_course(stamps, enu, sigma, segments, max_dt_s=window,
                                                    min_pairs=min_pairs)
        if travel < travel_m or not inl.any():
            return None
        heading = np.unwrap(np.interp(stamps, self.chain_t, np.unwrap(self.chain_heading)))
        if np.ptp(heading[inl]) > np.radians(c.ins_align_max_turn_deg):  # turning: no mean heading, pair by pair
            yaw, spread = heading_offset_turning(stamps, enu, segments, sigma, heading=heading, moved=moved,
                                                 min_pairs=min_pairs, max_dt_s=window)
            if spread > np.radians(min(max_spread_deg, TURNING_SPREAD_DEG)):
                return None
        else:
            if spread > np.radians(max_spread_deg):
                return None
            mean_heading = float(np.median(heading[inl]))  # a median: one false scan-to-map yaw is a spike
            if drove_backwards(ant[-1, :2] - ant[0, :2], mean_heading, travel):
                mean_heading += np.pi
            yaw = float(np.arctan2(np.sin(mean_heading - course), np.cos(mean_heading - course)))
        rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        early = sel & (self.gnss.stamps <= self.chain_t[0] + c.ins_origin_s)
        if early.sum() == 0:
            early = sel & (self.gnss.stamps <= stamps[min(4, stamps.size - 1)])
        chain_xy = np.column_stack([np.interp(self.gnss.stamps[early], self.chain_t, ant[:, i]) for i in range(2)])
        offset = np.median(chain_xy - self.gnss.enu[early, :2] @ rot.T, axis=0)
        return EnuAlignment(rot=rot, t=offset, yaw_rad=yaw)

    def fixes_until(self, t: float, velocity: np.ndarray, chain_z: float) -> list[FixUpdate]:
        """The usable fixes since the last call up to t (at most ins_max_fix_age_s old), as antenna
        positions at t (moved by the chain's velocity over t - stamp)."""
        if self.alignment is None:
            return []
        out = []
        end = int(np.searchsorted(self.gnss.stamps, t, side="right"))
        for i in range(self.next_fix, end):
            dt = t - float(self.gnss.stamps[i])
            if not self.usable[i] or dt > self.cfg.ins_max_fix_age_s:
                continue
            xy = self.alignment.to_map(self.gnss.enu[i, :2]) + velocity[:2] * dt
            var = np.diag(self.gnss.covariance[i])[:2]
            sig = np.sqrt(np.maximum(var, self.cfg.ins_sigma_floor_m ** 2))
            out.append(FixUpdate(stamp=float(self.gnss.stamps[i]), position=np.r_[xy, chain_z],
                                 sigmas=np.r_[sig, self.cfg.ins_vertical_sigma_m]))
        self.next_fix = max(self.next_fix, end)
        return out

    def judge(self, fix: FixUpdate, predicted_xy: np.ndarray, chain_cov_xy: np.ndarray) -> tuple[bool, np.ndarray]:
        """Gate one fix; returns whether it enters and its position (2,) less the current multipath
        offset. Its innovation is tested against graph #2's covariance (chi-square) and, with
        ins_trend_min_fixes in the last ins_trend_window_s, against a robust line through their
        innovations (within ins_trend_sigmas of its sigma plus ins_trend_floor_m): graph #2's
        covariance does not know the drift a tilted attitude's gravity leak makes, a drifting chain
        moves the line, a multipath jump is a step off it. ins_trend_of = accepted: the line of the
        accepted fixes decides alone; all: the line of every fix, and either test lets a fix in.
        With ins_step_fixes > 0, that many rejected fixes in a row that agree with each other are a
        multipath step whose size is taken off every later fix. After a run of rejections longer
        than ins_reacquire_s every fix enters until one passes again."""
        c = self.cfg
        sigma = float(fix.sigmas[0])
        xy = fix.position[:2] - self.offset
        innovation = xy - predicted_xy
        ok, _ = gate_fix(innovation, chain_cov_xy, fix.sigmas[:2] ** 2, c.ins_gate_chi2)
        self.history = [(t, v) for t, v in self.history if t >= fix.stamp - c.ins_trend_window_s]
        every = c.ins_trend_of == "all"
        if every:
            self.history.append((fix.stamp, innovation))
        trend = None
        if len(self.history) >= c.ins_trend_min_fixes and not (every and ok):  # the fixes' own trend decides
            t = np.array([h[0] for h in self.history]) - fix.stamp
            trend = robust_line(t, np.array([h[1] for h in self.history]), sigma)
            ok = bool(np.linalg.norm(innovation - trend) <= c.ins_trend_sigmas * sigma + c.ins_trend_floor_m)
        if not ok and trend is not None and c.ins_step_fixes > 0:
            ok, xy = self._step(fix, xy, innovation - trend, sigma)
        if ok:
            self.reacquiring = False
            self.pending, self.pending_t = [], []
        elif self.rejected_since is not None and fix.stamp - self.rejected_since >= c.ins_reacquire_s:
            self.reacquiring = True  # the chain diverged: the offset is no longer known either
            self.history, self.pending, self.pending_t, self.offset = [], [], [], np.zeros(2)
        if ok or self.reacquiring:
            self.accepted += 1
            self.rejected_since = None
            if not every:
                self.history.append((fix.stamp, fix.position[:2] - self.offset - predicted_xy))
            return True, xy
        self.rejected += 1
        if self.rejected_since is None:
            self.rejected_since = fix.stamp
        return False, xy

    def _step(self, fix: FixUpdate, xy: np.ndarray, off_trend: np.ndarray, sigma: float) -> tuple[bool, np.ndarray]:
        """A rejected fix joins the pending run; a flat run within ins_max_offset_m is a multipath step,
        taken off from now on."""
        c = self.cfg
        self.pending.append(off_trend)
        self.pending_t.append(fix.stamp)
        if len(self.pending) < c.ins_step_fixes:
            return False, xy
        steps = np.array(self.pending[-c.ins_step_fixes:])
        step = np.median(steps, axis=0)
        if np.linalg.norm(self.offset + step) <= c.ins_max_offset_m and \
                np.all(np.linalg.norm(steps - step, axis=1) <= 2.0 * sigma + 0.1):
            self.offset = self.offset + step
            self.steps += 1
            return True, xy - step
        return False, xy


def build(gnss: GnssSeries | None, cfg: GpsConfig, antenna_in_sensor: np.ndarray | None,
          base_to_sensor: np.ndarray | None, with_wheels: bool) -> GnssIns | None:
    """The GNSS/INS when slam.gps.ins asks for it and the log has fixes (None otherwise)."""
    if gnss is None or not cfg.enabled or gnss.stamps.size == 0 or cfg.ins == "off" \
            or (cfg.ins == "without_wheels" and with_wheels):
        return None
    return new_ins(gnss, cfg, antenna_in_sensor, base_to_sensor)


def new_ins(gnss: GnssSeries, cfg: GpsConfig, antenna_in_sensor: np.ndarray | None,
            base_to_sensor: np.ndarray | None, max_var_m2: float | None = None) -> GnssIns:
    """A GnssIns for the log's frames (no antenna: at the sensor; no base_link: the sensor's x forward);
    `max_var_m2`: the fixes' variance limit when not gps_cov_threshold_m2."""
    base = np.eye(4) if base_to_sensor is None else np.asarray(base_to_sensor, float)
    antenna = np.zeros(3) if antenna_in_sensor is None else np.asarray(antenna_in_sensor, float)
    return GnssIns(gnss=gnss, cfg=cfg, forward_in_lidar=base[:3, :3].T @ np.array([1.0, 0.0, 0.0]),
                   antenna_in_lidar=antenna, max_var_m2=max_var_m2)


def step(ins: GnssIns, odom: ImuOdometry, matched: np.ndarray, t: float, events: list[SlamEvent]) -> np.ndarray:
    """After graph #2 took the sweep's scan-to-map pose at t: fix the alignment when it can be, then
    the fixes since the last sweep into graph #2; returns the sweep's pose (graph #2's fused pose
    once aligned, else the matched pose)."""
    ins.observe(t, matched)
    align = ins.try_align(t)
    if align is not None:
        odom.degenerate_sigma = ins.cfg.ins_degenerate_sigma
        odom.acc_bias_walk = max(ins.cfg.ins_acc_bias_walk, odom.cfg.acc_bias_noise)
        odom.use_acc_noise(ins.cfg.ins_acc_noise)
        odom.marginal_restarts = ins.cfg.ins_marginal_restarts
        events.append(SlamEvent(t=t, kind="gps", message=f"GNSS/INS: ENU -> map alignment fixed from the fixes' "
                                f"course: yaw {np.degrees(align.yaw_rad):.1f} deg", data={"yaw_rad": align.yaw_rad}))
    fused = odom.lidar_pose()
    if ins.alignment is None or fused is None:
        return matched
    z = float((fused[:3, :3] @ ins.antenna_in_lidar + fused[:3, 3])[2])
    failed = odom.add_fixes(ins.fixes_until(t, odom.velocity, z), ins.antenna_in_lidar, ins.judge,
                            ins.cfg.ins_huber_k)
    if failed:  # said, not silent: the run goes on from the matched pose
        events.append(SlamEvent(t=t, kind="gps", message=failed, data={"gnss_ins_failed": True}))
    out = odom.lidar_pose()
    return matched if out is None else out
