"""x and y from the fixes where the LiDAR cannot see them and no wheel odometry is used.

On bare ground scan-to-map pins z, roll and pitch (the ground) and leaves x, y and yaw to the IMU;
without wheels that is accelerometer dead reckoning, whose horizontal error grows by ~0.5 m/s^2 on
the field IMU (turn-on bias and vibration), and graph #1's GNSS factors cannot reach graph #2's
velocity (docs/simulation.md, issue 28). Here the fixes themselves carry x and y along the directions
a degenerate match leaves free, exactly where wheels would otherwise carry them (replay.wheel_guess):

- a causal constant-velocity Kalman filter on the fixes (ENU, m), its acceleration noise
  `track_accel_sigma`; each fix gated on its innovation (chi-square, 2 dof);
- a multipath jump is a held offset (0.5-3 m for seconds): `track_step_fixes` rejected fixes in a row
  that agree with each other are a step, taken off the later fixes until they step back (an offset
  held for 10 s is dropped: multipath does not last that long, a filter error would); and dropped
  earlier when the fixes' velocity over `track_lag_check_s` after the step disagrees with the
  filter's before it: the filter was lagging (overlapping jumps had dragged its velocity), not the
  fixes jumping; or, `track_box_check_s`, when the fixes say the step ended a jump the filter had
  followed below the gate (a box offset before the step fits them better than the step held): the
  offset-free hypothesis, the offset goes to zero;
- by default (`track_model` hypotheses) the filter is slam/gnss_bank.OffsetBank instead: the offset a
  state, its changes weighted hypotheses, no gate and no step rule (the step filter: `track_model` steps);
- an outage (no fix taken for `track_max_gap_s`) hands x, y back to the chain until the fixes return,
  and the filter starts again at the first of them;
- the ENU -> map alignment from the fixes' own course against the gyro's heading, fixed once
  (slam/gnss_ins.py's), so a drifting chain cannot slide it; until it is fixed (5 m of travel), a
  provisional one from `track_provisional_travel_m` (3 m) carries x, y instead of IMU dead reckoning
  (replaced once: one step in the online trajectory);
- the sweep's pose keeps its rotation, z and every direction scan-to-map measured; only its
  translation along the match's degenerate directions moves to the track (the antenna lever arm
  taken off)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.data import GnssSeries
from mrnc_eval.geometry import rotation
from mrnc_eval.slam.config import GpsConfig
from mrnc_eval.slam.gnss_bank import OffsetBank
from mrnc_eval.slam.gnss_ins import EnuAlignment, GnssIns, new_ins

CHI2_2DOF = 13.8  # 0.1 % of consistent fixes rejected
# A provisional alignment from a short stretch needs a course many pairs agree on: on open line seed 2
# (float) a 2.4 m multipath jump 2.2 s in gave 5 pairs at 2.1 m of travel (3.1 s) at -106 deg and 22
# pairs spread 44 deg at 4.7 s (the truth ~0 deg); from 20 pairs spread <= 15 deg, within 2 deg.
PROVISIONAL_PAIRS = 20
PROVISIONAL_SPREAD_DEG = 15.0
# The offset-free check (TrackFilter._check_box) needs this long of fixes before a box (s): they are
# what tells a jump the filter absorbed from the step (with 1 s, a genuine 3.4 m step on open line seed 2
# was taken for the end of a box).
PRE_BOX_S = 3.0
KEEP_PRE_S = 6.0  # ... and keeps up to this long of them (s): a quadratic through 3 s bends into an 8 s box
SWAY_KEEP = 8  # the sway of this many latest sweeps is kept (the fixes fed at a sweep are since the last one)


@dataclass(kw_only=True)
class LagCheck:
    """A step under test: the filter's velocity (m/s) and its covariance just before it, and the fixes
    taken after it."""

    since: float
    v: np.ndarray
    p_vv: np.ndarray
    stamps: list[float] = field(default_factory=list)
    fixes: list[np.ndarray] = field(default_factory=list)  # accepted since, the held offset taken off (ENU, m)


@dataclass(kw_only=True)
class BoxCheck:
    """A step under test against the offset-free hypothesis: when it was taken (s), the held offset
    before it and the step (ENU, m)."""

    since: float
    before: np.ndarray
    step: np.ndarray


@dataclass(kw_only=True)
class TrackFilter:
    """Constant-velocity Kalman filter in ENU: state [x, y, vx, vy] (m, m/s)."""

    accel_sigma: float  # m/s^2, white acceleration
    step_fixes: int
    max_offset_m: float
    max_gap_s: float = 2.0  # no fix taken for longer: the filter starts again at the next fix
    offset_max_s: float = 10.0  # a held offset older than this is no multipath jump: the fixes are right
    lag_check_s: float = 0.0  # after a step, re-check it against a velocity from this long of fixes (0: off)
    sigma_floor_m: float = 0.0  # a fix's sigma is taken as at least this (m): what the model cannot follow
    x: np.ndarray | None = None
    p: np.ndarray = field(default_factory=lambda: np.eye(4))
    t: float = 0.0
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))  # held multipath offset, m
    offset_since: float = 0.0  # when the held offset was taken, s
    pending: list[np.ndarray] = field(default_factory=list)  # innovations of the latest rejected run, m
    accepted: int = 0
    rejected: int = 0
    steps: int = 0
    lag_drops: int = 0  # held offsets dropped because the filter's velocity before them was wrong
    check: LagCheck | None = None  # the latest step, under test
    box_window_s: float = 0.0  # a step is tested against an absorbed jump ending at it, this far back (0: off)
    box_after_s: float = 2.0  # ... once this long of fixes after the step is in
    box_chi2: float = 20.0  # ... the offset-free fit better by this much (in sigma^2) drops the step
    history: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)  # (s, fix, held offset), m
    box: BoxCheck | None = None
    box_drops: int = 0

    def fresh(self, t: float) -> bool:
        """A fix was taken within max_gap_s before t (else the filter only extrapolates)."""
        return self.x is not None and t - self.t <= self.max_gap_s

    def predict(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """State and covariance at t (not stored)."""
        assert self.x is not None
        dt = max(t - self.t, 0.0)
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        g = np.array([[dt * dt / 2, 0.0], [0.0, dt * dt / 2], [dt, 0.0], [0.0, dt]])
        return f @ self.x, f @ self.p @ f.T + self.accel_sigma ** 2 * (g @ g.T)

    def update(self, t: float, z: np.ndarray, sigma: float) -> bool:
        """One fix (ENU xy, m; its 1-sigma, m); returns whether it entered. After max_gap_s without a
        fix taken (an outage, or the track lost) the filter starts again at this fix; a held offset
        older than offset_max_s is dropped (the position keeps what it was)."""
        sigma = max(sigma, self.sigma_floor_m)
        if self.x is None or t - self.t > self.max_gap_s:
            self.x, self.t, self.offset, self.pending = np.r_[z, 0.0, 0.0], t, np.zeros(2), []
            self.check = self.box = None
            self.history = []  # fixes before a restart are no smooth track with the ones after it
            self.p = np.diag([sigma ** 2, sigma ** 2, 1.0, 1.0])
            return True
        if np.any(self.offset) and t - self.offset_since > self.offset_max_s:
            self.x[:2], self.offset = self.x[:2] + self.offset, np.zeros(2)
        if self.box_window_s > 0:
            self._remember(t, z)
        x, p = self.predict(t)
        nu = z - self.offset - x[:2]
        s = p[:2, :2] + sigma ** 2 * np.eye(2)
        if float(nu @ np.linalg.solve(s, nu)) > CHI2_2DOF and not self._step(nu, sigma):
            self.rejected += 1
            return False
        nu = z - self.offset - x[:2]
        gain = p[:, :2] @ np.linalg.inv(p[:2, :2] + sigma ** 2 * np.eye(2))
        self.x, self.p, self.t = x + gain @ nu, (np.eye(4) - gain @ np.eye(4)[:2]) @ p, t
        self.accepted += 1
        self.pending = []
        self._check_lag(t, z - self.offset, sigma)
        self._check_box(t, sigma)
        return True

    def _remember(self, t: float, fix: np.ndarray) -> None:
        self.history.append((t, fix, self.offset.copy()))
        keep = self.box_window_s + self.box_after_s + KEEP_PRE_S
        while self.history and self.history[0][0] < t - keep:
            self.history.pop(0)

    def _check_box(self, t: float, sigma: float) -> None:
        """The offset-free hypothesis against a step held (box_after_s after it): the step is not a jump
        starting but the end of one the filter absorbed (it followed jumped fixes below the gate, or a
        change of a held jump), and the fixes after it are clean. Then the fixes since the offset held
        before the step was taken (less it) fit a smooth track with a box offset ending at the step and
        the later fixes as they are, better than with the new offset held: the offset goes to zero and
        the filter to that track."""
        c = self.box
        if c is None or t - c.since < self.box_after_s:
            return
        self.box = None
        # back to the latest fix that came with another offset held (its correction may itself be wrong)
        start = max((i + 1 for i, (ts_i, _, off) in enumerate(self.history)
                     if ts_i <= c.since and np.any(off != c.before)), default=0)
        ts = np.array([h[0] for h in self.history[start:]])
        after = ts > c.since
        fixes = np.array([z - (0.0 if a else off) for (_, z, off), a in zip(self.history[start:], after, strict=True)])
        # with no offset held before, the absorbed jump was -step (the step is its end): a box of that offset
        box = None if np.any(c.before) else -c.step
        fit = _box_fit(ts - t, fixes, after, c.before + c.step, box=box, step_at=c.since - t,
                       window_s=self.box_window_s)
        if fit is None or fit[0] < self.box_chi2 * sigma ** 2:
            return
        assert self.x is not None
        self.offset = np.zeros(2)
        self.x[:2], self.x[2:] = fit[1], fit[2]
        self.check = None
        self.box_drops += 1

    def _check_lag(self, t: float, z: np.ndarray, sigma: float) -> None:
        """A step is the fixes moving against a filter that was right. If the velocity of the fixes
        after it (a straight line through them) disagrees with the filter's velocity before it, the
        filter was lagging (its own error taken for a jump): the held offset is dropped, the fixes kept.
        A line the fixes do not fit (another jump inside) decides nothing."""
        c = self.check
        if c is None:
            return
        c.stamps.append(t)
        c.fixes.append(z)
        if t - c.since < self.lag_check_s:
            return
        self.check = None
        dt = np.array(c.stamps) - np.mean(c.stamps)
        if len(dt) < 3 or float(dt @ dt) <= 0.0:  # too few fixes in the window for a line (sparse fixes)
            return
        fixes = np.array(c.fixes)
        v = dt @ (fixes - fixes.mean(axis=0)) / float(dt @ dt)
        resid = fixes - fixes.mean(axis=0) - np.outer(dt, v)
        if np.any(np.linalg.norm(resid, axis=1) > 3.0 * sigma + 0.1):
            return
        var_v = sigma ** 2 / float(dt @ dt)
        d = v - c.v
        if float(d @ np.linalg.solve(c.p_vv + var_v * np.eye(2), d)) > CHI2_2DOF:
            assert self.x is not None
            self.x[:2], self.x[2:], self.offset = self.x[:2] + self.offset, v, np.zeros(2)
            self.p[2:, 2:] = np.maximum(self.p[2:, 2:], var_v * np.eye(2))
            self.lag_drops += 1

    def _step(self, nu: np.ndarray, sigma: float) -> bool:
        """A rejected fix joins the run; a run of step_fixes that agree is a multipath step (on or
        off), added to the held offset. True when this fix completed one. An offset beyond
        max_offset_m is no jump a receiver makes: the filter lost the track and restarts at the fixes."""
        self.pending.append(nu)
        if len(self.pending) < self.step_fixes:
            return False
        run = np.array(self.pending[-self.step_fixes:])
        step = np.median(run, axis=0)
        if np.any(np.linalg.norm(run - step, axis=1) > 3.0 * sigma + 0.1):
            return False
        old, new = self.offset.copy(), self.offset + step
        if np.linalg.norm(new) > self.max_offset_m:
            assert self.x is not None
            self.x[:2] = self.x[:2] + new
            new = np.zeros(2)
        self.offset, self.offset_since = new, float(self.t)
        self.steps += 1
        self.check = None
        self.box = None
        if self.box_window_s > 0 and np.any(new):
            self.box = BoxCheck(since=float(self.t), before=old, step=step)
        if self.lag_check_s > 0 and np.any(new):
            x, p = self.predict(self.t)
            self.check = LagCheck(since=float(self.t), v=x[2:], p_vv=p[2:, 2:])
        self.pending = []
        return True


@dataclass(kw_only=True)
class GnssTrack:
    """The filter fed with every usable fix up to each sweep, and the alignment (via GnssIns)."""

    ins: GnssIns
    filter: TrackFilter | OffsetBank
    provisional_travel_m: float = 0.0  # a provisional alignment after this much travel (0: none)
    provisional: EnuAlignment | None = None  # used until the final alignment (ins.alignment) is fixed
    next_fix: int = 0
    engaged: bool = False  # the replay has moved a sweep to the track
    engaged_final: bool = False  # ... on the final alignment (not the provisional one)
    up_in_lidar: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))  # the base's up axis
    level_antenna: bool = False  # the filter tracks the antenna with the base's tilt taken off (track_level_antenna)
    both_axes: bool = False  # a sweep with a horizontal direction free takes x and y from the track (track_both_axes)
    sway: list[np.ndarray] = field(default_factory=list)  # the latest sweeps' tilt sway (map xy, m; ins.chain_t's tail)

    def alignment(self) -> EnuAlignment | None:
        """The final alignment once fixed, else the provisional one (or None)."""
        return self.ins.alignment if self.ins.alignment is not None else self.provisional

    def antenna_xy(self, t: float, pose: np.ndarray) -> np.ndarray | None:
        """The antenna's map x, y at t by the fixes (None before any alignment); `pose` is the
        sweep's LiDAR pose as matched, for the alignment's heading."""
        ins = self.ins
        ins.observe(t, pose)
        if ins.alignment is None:
            ins.try_align(t)
        if ins.alignment is None and self.provisional is None and self.provisional_travel_m > 0:
            self.provisional = ins.fit_alignment(t, self.provisional_travel_m, PROVISIONAL_SPREAD_DEG,
                                                 PROVISIONAL_PAIRS)
        align = self.alignment()
        sway = np.zeros(2)
        if self.level_antenna:
            sway = tilt_sway(pose, ins.antenna_in_lidar, self.up_in_lidar)
            self.sway.append(sway)
            del self.sway[:-SWAY_KEEP]
        self._feed(t, align)
        if align is None or not self.filter.fresh(t):
            return None  # before the alignment, or no fix for a while (an outage): the chain's own x, y
        x, _ = self.filter.predict(t)
        return np.asarray(align.to_map(x[:2]) + sway, np.float64)

    def _feed(self, t: float, align: EnuAlignment | None) -> None:
        """The usable fixes up to t into the filter; once aligned (the sway is in map axes), each less the
        antenna's sway with the base's tilt at its stamp (interpolated between the observed sweeps): the
        filter tracks the antenna as if the base were level, a point that moves along the course and
        not +-0.2 m across it with the base's roll on rough ground."""
        ins, gnss = self.ins, self.ins.gnss
        end = int(np.searchsorted(gnss.stamps, t, side="right"))
        to_enu = align.rot.T if align is not None and self.level_antenna else None  # map -> ENU axes
        # the latest sweeps only: the fixes fed now are from since the last one
        ts, sway = np.asarray(ins.chain_t[len(ins.chain_t) - len(self.sway):]), np.asarray(self.sway)
        for i in range(self.next_fix, end):
            if ins.usable[i]:
                sigma = float(np.sqrt(np.max(np.diag(gnss.covariance[i])[:2])))
                stamp, z = float(gnss.stamps[i]), gnss.enu[i, :2]
                if to_enu is not None:
                    z = z - to_enu @ np.array([np.interp(stamp, ts, sway[:, k]) for k in range(2)])
                self.filter.update(stamp, z, sigma)
        self.next_fix = max(self.next_fix, end)

    def velocity_map(self, t: float) -> np.ndarray:
        """The filter's horizontal velocity (map, m/s) at t; zero before the alignment."""
        align = self.alignment()
        if align is None or self.filter.x is None:
            return np.zeros(2)
        x, _ = self.filter.predict(t)
        return np.asarray(align.rot @ x[2:], np.float64)


def tilt_sway(pose: np.ndarray, antenna_in_lidar: np.ndarray, up_in_lidar: np.ndarray) -> np.ndarray:
    """The horizontal displacement (map, m) of the antenna by the base's roll and pitch in `pose` (the
    LiDAR's, 4x4): the lever arm as posed, less the lever arm with the base's up axis turned back to
    vertical by the smallest rotation (the heading kept). A 2.2 m mast on a base rolled by 5 deg: 0.19 m."""
    rot = pose[:3, :3]
    up = rot @ up_in_lidar
    k = np.cross(up, [0.0, 0.0, 1.0])  # axis * sin(tilt)
    s, c = float(np.linalg.norm(k)), float(up[2])
    if s < 1e-12:
        return np.zeros(2)
    level = rotation.exp(k / s * np.arctan2(s, c))  # takes `up` to vertical
    arm = rot @ antenna_in_lidar
    return np.asarray((arm - level @ arm)[:2], np.float64)


def _box_fit(dt: np.ndarray, fixes: np.ndarray, after: np.ndarray, held: np.ndarray, *, box: np.ndarray | None,
             step_at: float, window_s: float) -> tuple[float, np.ndarray, np.ndarray] | None:
    """Fixes (n, 2; m) at dt (s, 0 = now) as a quadratic track: with the offset `held` (m) taken off the
    fixes after step_at (`after`), against the fixes as they are with a box offset (`box`, m, or
    fitted when None) over [tau, step_at] for the best tau up to window_s before it, PRE_BOX_S of
    fixes before any box.
    Returns how much smaller the box's residual sum of squares is (m^2), and its fit's position and
    velocity now (m, m/s); None when the window has too few fixes."""
    if (~after).sum() < 10 or after.sum() < 5:
        return None
    base = np.c_[np.ones_like(dt), dt, dt * dt]
    rss_held = _rss(base, fixes - np.outer(after, held))[0]
    best = _rss(base, fixes)  # no box: the fixes were clean all along
    first = dt[0] + PRE_BOX_S
    for tau in dt[(dt >= max(first, step_at - window_s)) & (dt <= step_at - 1.0)]:
        inside = (dt >= tau) & (dt <= step_at)
        fit = _rss(np.c_[base, inside], fixes) if box is None else _rss(base, fixes - np.outer(inside, box))
        if fit[0] < best[0]:
            best = fit
    return rss_held - best[0], best[1][0], best[1][1]


def _rss(a: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """Least squares of y (n, 2) on columns a (n, k): residual sum of squares and coefficients (k, 2)."""
    a = a.astype(float)  # the box column is boolean
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.sum((y - a @ coef) ** 2)), coef


def build(gnss: GnssSeries | None, cfg: GpsConfig, antenna_in_sensor: np.ndarray | None,
          base_to_sensor: np.ndarray | None, with_wheels: bool) -> GnssTrack | None:
    """The track when slam.gps.track asks for it: fixes in the log, GNSS on, no wheel odometry used."""
    if gnss is None or not gnss.stamps.size or not cfg.enabled or cfg.track != "without_wheels" or with_wheels:
        return None
    base = np.eye(4) if base_to_sensor is None else np.asarray(base_to_sensor, float)
    limit = max(cfg.gps_cov_threshold_m2, cfg.track_cov_threshold_m2)
    return GnssTrack(ins=new_ins(gnss, cfg, antenna_in_sensor, base_to_sensor, limit),
                     up_in_lidar=base[:3, :3].T @ np.array([0.0, 0.0, 1.0]), level_antenna=cfg.track_level_antenna,
                     both_axes=cfg.track_both_axes,
                     provisional_travel_m=cfg.track_provisional_travel_m,
                     filter=track_filter(cfg))


def track_filter(cfg: GpsConfig) -> TrackFilter | OffsetBank:
    """The track's filter as slam.gps configures it (the run's, and a diagnosis of the fixes alone)."""
    if cfg.track_model == "hypotheses":
        return OffsetBank(accel_sigma=cfg.track_accel_sigma, jump_sigma_m=cfg.track_jump_sigma_m,
                          on_rate_hz=cfg.track_jump_on_hz, off_rate_hz=cfg.track_jump_off_hz,
                          keep=cfg.track_hypotheses, max_gap_s=cfg.track_max_gap_s,
                          sigma_floor_m=cfg.track_sigma_floor_m)
    return TrackFilter(accel_sigma=cfg.track_accel_sigma, step_fixes=cfg.track_step_fixes,
                       max_offset_m=cfg.ins_max_offset_m, max_gap_s=cfg.track_max_gap_s,
                       sigma_floor_m=cfg.track_sigma_floor_m, lag_check_s=cfg.track_lag_check_s,
                       box_window_s=cfg.track_box_check_s)


def move_along_free(pose: np.ndarray, antenna_in_lidar: np.ndarray, antenna_xy: np.ndarray,
                    directions: np.ndarray, *, both_axes: bool = False) -> np.ndarray:
    """The pose with its translation moved toward putting the antenna at antenna_xy (map, m), only
    within the span of the translation parts of `directions` (k, 6; [rot, trans], map axes) and in
    x, y: what the match measured stays. both_axes: when that span has a horizontal direction, x and
    y both go to antenna_xy (the other horizontal direction the match measured is not kept)."""
    ant = pose[:3, :3] @ antenna_in_lidar + pose[:3, 3]
    want = np.r_[antenna_xy - ant[:2], 0.0]
    trans = np.asarray(directions, float)[:, 3:6].copy()
    trans[:, 2] = 0.0
    u, s, _ = np.linalg.svd(trans.T, full_matrices=False)
    basis = u[:, s > 0.5]  # horizontal directions the match left free
    if both_axes and basis.shape[1] > 0:
        basis = np.eye(3)[:, :2]
    out = pose.copy()
    out[:3, 3] += basis @ (basis.T @ want)
    return out
