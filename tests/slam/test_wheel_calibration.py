"""Online wheel calibration, the wheel gate and wheel_health on synthetic drives with known wheel
errors (the simulator's error model, sim/wheels.py), and the GNSS residual gate. Negative
controls: wheels with a known error must be flagged, exact and calibrated-class wheels must not;
a chain that agrees with GNSS gets no factor, one that drifted does, multipath does not move it."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.data import GnssSeries, ImuSeries
from mrnc_eval.sim.wheels import WheelErrors, measured_speeds
from mrnc_eval.slam.config import GpsConfig, WheelCalibrationConfig
from mrnc_eval.slam.gnss_gate import gate
from mrnc_eval.slam.wheel_calibration import WheelCalibrator, WheelIncrements, fit_scale, integrate
from mrnc_eval.slam.wheel_health import wheel_health
from mrnc_eval.slam.wheel_odometry import WheelTrack

TRACK = 1.6
GYRO_BIAS = 0.012  # rad/s, a field-profile turn-on bias


def _drive(duration_s: float = 40.0, rate: float = 50.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True forward speed and yaw rate of a drive with a standing start, speed changes and turns."""
    t = np.arange(0.0, duration_s, 1.0 / rate)
    v = np.clip((t - 1.0) / 3.0, 0.0, 1.0) * (0.8 + 0.2 * np.sin(2 * np.pi * t / 17.0))
    w = 0.25 * np.sin(2 * np.pi * t / 12.0) * (t > 5.0) * v
    return t, v, w


def _wheel_track(t: np.ndarray, v: np.ndarray, w: np.ndarray, err: WheelErrors, seed: int) -> WheelTrack:
    vl, vr = v - 0.5 * w * TRACK, v + 0.5 * w * TRACK
    ml, mr = measured_speeds(vl, vr, TRACK, err, np.random.default_rng(seed))
    dt = np.diff(t)
    vm, wm = 0.5 * (ml + mr), (mr - ml) / TRACK
    inc = WheelIncrements(stamps=t, forward_m=vm[:-1] * dt, lateral_m=np.zeros(dt.size), yaw_rad=wm[:-1] * dt,
                          start=np.eye(4))
    return integrate(inc, inc.forward_m, inc.yaw_rad)


def _imu(t: np.ndarray, w: np.ndarray, seed: int) -> ImuSeries:
    rng = np.random.default_rng(seed + 100)
    ti = np.arange(t[0], t[-1], 0.01)
    wz = np.interp(ti, t, w) + GYRO_BIAS + rng.normal(0.0, 0.002, ti.size) + 0.01 * np.sin(2 * np.pi * 30 * ti)
    gyro = np.c_[np.zeros(ti.size), np.zeros(ti.size), wz]
    return ImuSeries(ti, np.tile([0.0, 0.0, 9.81], (ti.size, 1)), gyro, None, "imu")


CASES = {  # name: (errors, flagged)
    "exact": (WheelErrors(), False),
    "calibrated": (WheelErrors(scale_error=0.005, lr_mismatch=-0.005, track_factor=1.1, speed_noise_mps=0.05), False),
    "lr2": (WheelErrors(lr_mismatch=0.02), True),
    "combined": (WheelErrors(scale_error=-0.02, lr_mismatch=-0.02, track_factor=1.6, speed_noise_mps=0.05), True),
}


def _calibrate(err: WheelErrors, seed: int = 0) -> WheelCalibrator:
    t, v, w = _drive(seed=seed)
    cal = WheelCalibrator.build(_wheel_track(t, v, w, err, seed), _imu(t, w, seed), np.eye(4),
                                WheelCalibrationConfig())
    assert cal is not None
    cal.update(float(t[-1]))
    return cal


@pytest.mark.parametrize("name", list(CASES))
def test_wheel_health_flags_wrong_wheels_and_only_them(name: str) -> None:
    err, flagged = CASES[name]
    h = wheel_health(_calibrate(err))
    assert (h["verdict"] != "ok") == flagged, h
    # wheel yaw / true yaw = (1 + scale) x track factor
    assert h["track_factor"] == pytest.approx(err.track_factor * (1 + err.scale_error), rel=0.02)
    # the estimate's own sigma is honest: 0.003 without speed noise, 0.005 with 0.05 m/s
    assert h["lr_mismatch"] == pytest.approx(err.lr_mismatch, abs=max(0.003, 3 * h["lr_mismatch_sigma"]))
    assert h["lr_mismatch_sigma"] < 0.006
    assert h["rejected_fraction"] < 0.05


def test_calibrated_track_follows_the_true_heading() -> None:
    """The combined errors' heading error over 40 s: tens of degrees raw, 0.37 deg calibrated with
    the gyro blended in by inverse variance (its bias from the standing start); the raw track and
    the calibrated wheels' yaw alone (1.65 deg: the 0.05 m/s pickup noise random-walks it) are the
    negative controls."""
    err = CASES["combined"][0]
    t, v, w = _drive()
    true_yaw = np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]
    raw = _wheel_track(t, v, w, err, 0)
    cal = _calibrate(err)
    wheels_only = WheelCalibrator.build(raw, _imu(t, w, 0), np.eye(4),
                                        WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0))
    assert wheels_only is not None
    wheels_only.update(float(t[-1]))

    def yaw_err(track: WheelTrack) -> float:
        yaw = np.unwrap(Rotation.from_quat(track.quat_xyzw).as_euler("ZYX")[:, 0])
        return float(np.degrees(np.max(np.abs(yaw - true_yaw))))

    assert yaw_err(raw) > 20.0
    assert yaw_err(cal.track()) < 0.8 < 1.2 < yaw_err(wheels_only.track())
    assert cal.gyro_bias == pytest.approx(GYRO_BIAS, abs=0.002)


def test_gate_rejects_a_wheel_glitch_and_takes_the_gyro_yaw() -> None:
    """A 0.5 s stretch where one side reads 0.5 m/s too much (a stuck pickup): its bins fail the
    chi-square gate; the gate off (gate_chi2 huge) keeps them: the negative control."""
    t, v, w = _drive()
    stamps, positions, quat = _glitched(t, v, w)
    glitch = WheelTrack(stamps=stamps, positions=positions, quat_xyzw=quat)
    wheels_yaw = WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0)  # the gate alone, no gyro blending
    on = WheelCalibrator.build(glitch, _imu(t, w, 0), np.eye(4), wheels_yaw)
    off = WheelCalibrator.build(glitch, _imu(t, w, 0), np.eye(4), replace(wheels_yaw, gate_chi2=1e12))
    assert on is not None
    assert off is not None
    on.update(float(t[-1]))
    off.update(float(t[-1]))
    assert 2 <= on.n_rejected <= 6
    assert off.n_rejected == 0
    true_yaw = np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]

    def yaw_err(cal: WheelCalibrator) -> float:
        return float(np.max(np.abs(np.unwrap(Rotation.from_quat(cal.track().quat_xyzw).as_euler("ZYX")[:, 0])
                                   - true_yaw)))

    assert yaw_err(on) < 0.02 < 0.05 < yaw_err(off)  # the glitch itself is 0.16 rad
    assert abs(on.track_factor - 1.0) < 0.01 < 0.03 < abs(off.track_factor - 1.0)  # it bent the fit


def _glitched(t: np.ndarray, v: np.ndarray, w: np.ndarray,
              spans: tuple[tuple[float, float], ...] = ((20.0, 20.5),)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    track = _wheel_track(t, v, w, WheelErrors(), 0)
    inc = WheelIncrements.of(track)
    bad = np.zeros(t.size - 1, bool)
    for t0, t1 in spans:
        bad |= (t[:-1] >= t0) & (t[:-1] < t1)
    yaw = inc.yaw_rad + bad * 0.5 / TRACK * np.diff(t)
    out = integrate(inc, inc.forward_m, yaw)
    return out.stamps, out.positions, out.quat_xyzw


def test_one_burst_of_rejected_bins_early_is_not_unreliable_wheels() -> None:
    """A 1.4 s episode of wheel yaw off the gyro (one side on a wet patch: the yard circle's ideal
    wheels have one at 11.8-13.0 s) seen 13 s into the drive: 8 of 65 bins rejected, above the 10 %
    limit but not significantly (binomial sigma 3.7 % at 65 bins): `ok`. Negative control: a pickup
    that fails every 3 s all drive long (about a quarter of the bins) is `unreliable`."""
    t, v, w = _drive()
    wheels_yaw = WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0)

    def health(spans: tuple[tuple[float, float], ...], until: float) -> dict[str, Any]:
        stamps, positions, quat = _glitched(t, v, w, spans)
        cal = WheelCalibrator.build(WheelTrack(stamps=stamps, positions=positions, quat_xyzw=quat), _imu(t, w, 0),
                                    np.eye(4), wheels_yaw)
        assert cal is not None
        cal.update(until)
        return wheel_health(cal)

    burst = health(((11.6, 13.0),), 13.0)
    assert burst["rejected_fraction"] > wheels_yaw.flag_rejected_fraction
    assert burst["verdict"] == "ok", burst
    broken = health(tuple((t0, t0 + 0.8) for t0 in np.arange(6.0, 39.0, 3.0)), float(t[-1]))
    assert broken["rejected_fraction"] > 0.2
    assert broken["verdict"] == "unreliable", broken


# ---- scale against the LiDAR: slip on wet ground is not a scale error
# Keyframe distance steps as on the yard circle (straight steps, 0.9-1.2 m, LiDAR good to ~1 %); the
# steps crossing the wet patch over-read by 17-19 % (the plant's slip, measured against ground truth).
STEPS_LIDAR_M = np.array([1.17, 0.95, 0.80, 1.18, 0.92, 1.05])
ON_PATCH = np.array([False, False, True, False, False, True])


def _distance_steps(scale_error: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(wheel m, LiDAR m) per step: the wheels read (1 + scale_error) x the ground, x 1.18 on the patch."""
    rng = np.random.default_rng(seed)
    wheel = STEPS_LIDAR_M * (1 + scale_error) * np.where(ON_PATCH, 1.18, 1.0)
    return wheel, STEPS_LIDAR_M * (1 + rng.normal(0.0, 0.01, STEPS_LIDAR_M.size))


def _with_steps(wheel: np.ndarray, lidar: np.ndarray, cfg: WheelCalibrationConfig) -> dict[str, Any]:
    t, v, w = _drive()
    cal = WheelCalibrator.build(_wheel_track(t, v, w, WheelErrors(), 0), _imu(t, w, 0), np.eye(4), cfg)
    assert cal is not None
    cal.update(float(t[-1]))
    for wm, lm in zip(wheel, lidar, strict=True):
        cal.add_distance(float(wm), float(lm))
    return wheel_health(cal)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_slip_on_a_wet_patch_is_not_a_scale_error_but_a_real_one_is(seed: int) -> None:
    """Exact wheels whose steps over the wet patch over-read by 18 %: `ok`, the two steps counted
    as slip, the scale near 0. Negative controls: the same steps with a planted +4 % scale error
    (every step, on the patch too) are flagged for scale; the plain least-squares fit with the
    configured 2 cm per step (wheel_health's fit before) flags the slip alone as a +5 % scale; with
    the gate off (scale_gate_chi2 huge) the scale reads +5 % too, and only the sigma widened by the
    steps' scatter keeps it from being flagged."""
    cfg = WheelCalibrationConfig()
    slip = _with_steps(*_distance_steps(0.0, seed), cfg)
    assert slip["verdict"] == "ok", slip
    assert slip["slip_steps"] == 2
    assert slip["scale_steps"] == 4
    assert slip["slip_mean_over_read"] == pytest.approx(0.18, abs=0.03)
    assert abs(slip["scale_error"]) < 0.01
    real = _with_steps(*_distance_steps(0.04, seed), cfg)
    assert real["verdict"] == "miscalibrated", real
    assert any("scale error" in r for r in real["reasons"])
    assert real["scale_error"] == pytest.approx(0.04, abs=0.01)
    assert real["slip_steps"] == 2
    wheel, lidar = _distance_steps(0.0, seed)
    info = 1 / cfg.scale_prior_sigma ** 2 + np.sum(lidar ** 2) / cfg.scale_distance_sigma_m ** 2
    lsq = (1 / cfg.scale_prior_sigma ** 2 + np.sum(lidar * wheel) / cfg.scale_distance_sigma_m ** 2) / info - 1
    assert lsq > max(cfg.flag_scale, cfg.flag_sigmas / np.sqrt(info), 0.04)
    no_gate = _with_steps(wheel, lidar, replace(cfg, scale_gate_chi2=1e12))
    assert no_gate["scale_error"] > 0.04
    assert no_gate["slip_steps"] == 0
    assert no_gate["scale_error_sigma"] > 2 / np.sqrt(info)
    assert no_gate["verdict"] == "ok"


def test_scale_sigma_follows_the_scatter_when_steps_cannot_tell_slip_from_scale() -> None:
    """Two steps that disagree by 17 % (one slipped, which one is unknown): no step is called slip,
    and the sigma is widened by their scatter (chi-square / dof) instead of the configured 2 cm per
    step, so the 9 % mean is not flagged. Control: two steps agreeing on +4 % keep the narrow sigma."""
    cfg = WheelCalibrationConfig()
    split = fit_scale(np.array([1.02, 1.19]), np.array([1.0, 1.0]), cfg)
    assert split.slip_steps == 0
    assert split.sigma > 0.05 > 0.02 > fit_scale(np.array([1.04, 1.04]), np.array([1.0, 1.0]), cfg).sigma
    assert fit_scale(np.zeros(0), np.zeros(0), cfg).sigma == cfg.scale_prior_sigma


# ---- GNSS residual gate
def _line_chain(n: int = 30, drift_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Keyframes 1 s / 1 m apart along x; the last 8 drift sideways by up to drift_m."""
    stamps = np.arange(n, dtype=float)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = stamps
    poses[:, 1, 3] = np.clip(stamps - (n - 9), 0.0, None) / 8.0 * drift_m
    return stamps, poses


def _fixes(n: int, sigma: float, seed: int, multipath: tuple[float, float] | None = None) -> GnssSeries:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, n - 1 + 1e-9, 0.2)
    enu = np.c_[t, np.zeros(t.size), np.zeros(t.size)] + rng.normal(0.0, sigma, (t.size, 3))
    if multipath is not None:
        enu[(t >= multipath[0]) & (t < multipath[1]), 1] += 2.5
    cov = np.tile(np.diag([sigma ** 2] * 3), (t.size, 1, 1))
    return GnssSeries(stamps=t, lla=enu, enu=enu, covariance=cov, origin_lla=np.zeros(3))


def test_gnss_gate_lets_fixes_in_only_when_the_chain_drifted() -> None:
    cfg = GpsConfig()
    lever = np.zeros(3)
    fixes = _fixes(30, 0.3, 1)
    usable = np.ones(fixes.stamps.size, bool)
    ok, _ = gate(fixes, usable, *_line_chain(), lever, cfg)
    drifted, _ = gate(fixes, usable, *_line_chain(drift_m=1.5), lever, cfg)
    assert ok is not None
    assert ok.position is None  # the chain agrees: no factor
    assert drifted is not None
    assert drifted.position is not None
    # the factor pulls the last keyframe back towards y = 0 (the re-fitted alignment takes a part)
    assert drifted.position[1] < 1.5 - 0.5


def test_gnss_gate_drops_a_multipath_jump() -> None:
    """2.5 m multipath over 2 s of the 6 s window: its fixes are dropped as outliers; with the
    outlier test off (huge outlier_sigmas) none is (the negative control)."""
    fixes = _fixes(30, 0.3, 2, multipath=(25.0, 27.0))
    usable = np.ones(fixes.stamps.size, bool)
    d, _ = gate(fixes, usable, *_line_chain(), np.zeros(3), GpsConfig())
    assert d is not None
    assert d.position is None
    assert d.outliers >= 8
    loose, _ = gate(fixes, usable, *_line_chain(), np.zeros(3), GpsConfig(residual_outlier_sigmas=100.0))
    assert loose is not None
    assert loose.outliers == 0


def _overconfident(n: int, seed: int) -> GnssSeries:
    """Fixes that claim 2 cm (RTK) while multipath moves them by decimetres over seconds, as the
    field profile's receiver does near structures (0.9 m RMS off the truth on the open line)."""
    fixes = _fixes(n, 0.02, seed)
    t = fixes.stamps
    rng = np.random.default_rng(seed + 100)
    wander = 0.35 * np.sin(2 * np.pi * t / 7.0 + 1.0) + rng.normal(0.0, 0.15, t.size)
    enu = fixes.enu + np.c_[np.zeros(t.size), wander, np.zeros(t.size)]
    return GnssSeries(stamps=t, lla=enu, enu=enu, covariance=fixes.covariance, origin_lla=np.zeros(3))


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_gnss_gate_judges_fixes_by_their_scatter_not_their_claimed_sigma(seed: int) -> None:
    """An exact chain and overconfident fixes: no factor (one would pull the chain off by the
    fixes' multipath; the field-profile open line went 0.022 -> 0.158 m that way). The same fixes
    when the chain really drifted 3 m (half of it left after the re-fitted alignment): a factor.
    Negative control: with the claimed sigma taken as it is (the scatter bypassed), a factor
    enters on the exact chain."""
    from mrnc_eval.slam import gnss_gate

    fixes, cfg, lever = _overconfident(30, seed), GpsConfig(), np.zeros(3)
    usable = np.ones(fixes.stamps.size, bool)
    exact, _ = gate(fixes, usable, *_line_chain(), lever, cfg, chain_sigma_m=1.0)  # with wheels
    no_wheels, _ = gate(fixes, usable, *_line_chain(), lever, cfg)  # the scatter is the chain's there
    assert no_wheels is not None
    assert no_wheels.position is not None  # as before: without wheels the claim is taken
    drifted, _ = gate(fixes, usable, *_line_chain(drift_m=3.0), lever, cfg, chain_sigma_m=1.0)
    assert exact is not None
    assert exact.position is None
    assert drifted is not None
    assert drifted.position is not None
    real = gnss_gate._robust_line

    def trusting(dt: np.ndarray, res: np.ndarray, sig: np.ndarray, c: GpsConfig,  # type: ignore[no-untyped-def]
                 scatter_floor: bool = True):
        return real(dt, res, sig, c, scatter_floor=False)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(gnss_gate, "_robust_line", trusting)
        fooled, _ = gate(fixes, usable, *_line_chain(), lever, cfg, chain_sigma_m=1.0)
    assert fooled is not None
    assert fooled.position is not None


def test_calibrated_track_equals_the_per_bin_blend() -> None:
    """track() blends every consumed bin at once; the same as blending bin by bin (the rule it
    replaced), bit for bit, with rejected bins (the gyro's yaw) and blended ones, and the increments
    after the last consumed bin by the same weight."""
    t, v, w = _drive()
    stamps, positions, quat = _glitched(t, v, w)
    cal = WheelCalibrator.build(WheelTrack(stamps=stamps, positions=positions, quat_xyzw=quat), _imu(t, w, 0),
                                np.eye(4), WheelCalibrationConfig())
    assert cal is not None
    cal.update(float(t[-1]) * 0.8)
    assert cal.n_rejected >= 2  # the glitch's bins
    f, a, c = cal.theta
    dt = np.diff(cal.inc.stamps)
    yaw = (cal.inc.yaw_rad - a * cal.inc.forward_m - c * dt) / f
    var_w = max(cal.sigma2, 1e-12) / f ** 2
    w_gyro = var_w / (var_w + cal.cfg.gyro_yaw_rate_sigma_rad_s ** 2)
    assert 0.0 < w_gyro < 1.0
    for k in range(cal.next_bin):
        i0, i1 = cal.bins[0][k], cal.bins[1][k]
        weight = 1.0 if k in cal.rejected_bins else w_gyro
        gyro = cal.bin_yaw_gyro[k] * dt[i0:i1] / max(dt[i0:i1].sum(), 1e-9)
        yaw[i0:i1] = (1.0 - weight) * yaw[i0:i1] + weight * gyro
    tail = cal.bins[1][cal.next_bin - 1]  # the increments no bin has consumed: the same weight, ungated
    yaw[tail:] = (1.0 - w_gyro) * yaw[tail:] + w_gyro * cal.inc_yaw_gyro[tail:]
    expected = integrate(cal.inc, cal.inc.forward_m / cal.scale, yaw)
    np.testing.assert_array_equal(cal.track().quat_xyzw, expected.quat_xyzw)
    np.testing.assert_array_equal(cal.track().positions, expected.positions)


def _sweep_yaw_errors(cal: WheelCalibrator, t: np.ndarray, w: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """Per sweep stamp s (in order, the calibrator updated to s as the replay does): the error (deg) of
    the track's yaw increment over the 0.2 s before s, the increment a sweep's wheel guess takes."""
    true_yaw = np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]
    out = []
    for s in stamps:
        cal.update(float(s))
        track = cal.track()
        yaw = np.unwrap(Rotation.from_quat(track.quat_xyzw).as_euler("ZYX")[:, 0])
        est = np.diff(np.interp([s - 0.2, s], track.stamps, yaw))[0]
        out.append(est - np.diff(np.interp([s - 0.2, s], t, true_yaw))[0])
    return np.degrees(np.abs(out))


def test_a_sweeps_wheel_yaw_is_blended_with_the_gyro_up_to_the_sweep() -> None:
    """Calibrated-class wheels (0.05 m/s pickup noise) on the synthetic drive, sweeps at 5 Hz offset
    from the 0.2 s bins: the yaw increment over each sweep's last 0.2 s is within 0.1 deg of the
    truth, from the first sweep on (the gyro's bias measured over the standing start; worst measured
    0.06 deg). Negative control: the increments no bin has consumed take the calibrated wheels' yaw
    (the rule before): the pickup noise, 0.45 deg on the worst sweep."""
    err = CASES["calibrated"][0]
    t, v, w = _drive()
    stamps = np.arange(1.13, 39.0, 0.2)

    def calibrator() -> WheelCalibrator:
        cal = WheelCalibrator.build(_wheel_track(t, v, w, err, 0), _imu(t, w, 0), np.eye(4), WheelCalibrationConfig())
        assert cal is not None
        assert cal.standing_start
        return cal

    blended = _sweep_yaw_errors(calibrator(), t, w, stamps)
    off = calibrator()
    off.inc_yaw_gyro = off.inc.yaw_rad.copy()  # the tail's "gyro" is the wheels' own yaw: no blend there
    unblended = _sweep_yaw_errors(off, t, w, stamps)
    assert blended.max() < 0.12 < 0.25 < unblended.max()


def test_the_warm_up_takes_the_gyro_when_its_bias_was_measured() -> None:
    """The first 25 bins (5 s) before the wheel fit has its own statistics: with a standing start the
    track's heading follows the gyro (worst 0.05 deg over the first 4.9 s on calibrated-class wheels
    with an L/R mismatch of 0.5 %); negative control: the wheels' yaw alone there
    (gyro_yaw_rate_sigma 0, the rule before for the warm-up): 0.61 deg."""
    err = CASES["calibrated"][0]
    t, v, w = _drive()
    true_yaw = np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]
    errors = []
    for cfg in (WheelCalibrationConfig(), WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0)):
        cal = WheelCalibrator.build(_wheel_track(t, v, w, err, 0), _imu(t, w, 0), np.eye(4), cfg)
        assert cal is not None
        cal.update(4.9)
        assert cal.n_bins < cal.cfg.warmup_bins
        track = cal.track()
        yaw = np.unwrap(Rotation.from_quat(track.quat_xyzw).as_euler("ZYX")[:, 0])
        early = track.stamps <= 4.9
        errors.append(float(np.degrees(np.max(np.abs(yaw[early] - np.interp(track.stamps[early], t, true_yaw))))))
    assert errors[0] < 0.1 < 0.3 < errors[1]  # measured 0.05 and 0.61 deg


def test_the_yaw_hold_weighs_the_guess_s_yaw_not_the_wheels_alone() -> None:
    """yaw_quality scales the hold of the matched yaw towards the wheel guess, whose yaw is track()'s
    blend: calibrated-class wheels (0.05 m/s pickups, residual 0.015 rad/s) with a measured gyro bias
    are 98 % gyro, so the full hold (1.0); the wheels' yaw alone (gyro_yaw_rate_sigma 0) keeps the
    hold scaled by the calibrated wheels' variance, their residual over f^2 (0.57, f = 1.11). Negative
    control: the residual rule, the one before, gives the blended guess 0.47. With a tighter
    reference sigma the scale is the blend's information ratio, w^2 gyro + (1 - w)^2 wheels (0.25
    here, the residual rule's floor 0.05)."""
    err = CASES["calibrated"][0]
    t, v, w = _drive()
    quality, old, factor = [], [], []
    configs = (WheelCalibrationConfig(), WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0),
               WheelCalibrationConfig(yaw_rate_sigma_rad_s=0.001))
    for cfg in configs:
        cal = WheelCalibrator.build(_wheel_track(t, v, w, err, 0), _imu(t, w, 0), np.eye(4), cfg)
        assert cal is not None
        assert cal.standing_start
        cal.update(float(t[-1]))
        quality.append(cal.yaw_quality())
        factor.append(cal.track_factor)
        old.append(float(np.clip(cfg.yaw_rate_sigma_rad_s ** 2 / cal.sigma2, cfg.min_yaw_quality, 1.0)))
    assert quality[0] == 1.0
    assert 0.2 < quality[1] < 0.7
    assert quality[1] == pytest.approx(old[1] * factor[1] ** 2)
    assert old[0] < 0.7  # the residual rule would hold the gyro-dominated guess as weakly as the wheels
    wg = cal.gyro_weight()
    var = wg ** 2 * cal.cfg.gyro_yaw_rate_sigma_rad_s ** 2 + (1 - wg) ** 2 * cal.sigma2 / cal.track_factor ** 2
    assert quality[2] == pytest.approx(1e-6 / var, rel=1e-9)
    assert 0.1 < quality[2] < 0.6
    assert old[2] < 0.1


def test_the_yaw_hold_is_continuous_as_the_gyro_weight_goes_to_zero() -> None:
    """The guess's yaw is the calibrated wheels' (raw / f) when the gyro is not blended in (w = 0: no
    standing start, or gyro_yaw_rate_sigma 0), so yaw_quality there is the blend's limit as w -> 0
    (gyro_yaw_rate_sigma 100 rad/s, w ~ 1e-8): to 1e-6 on combined-class wheels (fitted f 1.57,
    reference sigma 0.005 rad/s so that the scale is not clipped: 0.29). Negative control: the
    wheels-only rule before (the raw residual variance, not over f^2) jumps to 0.12 there, f^2 = 2.47
    off; with the track factor at 1 the two rules agree."""
    t, v, w = _drive()
    cfg = WheelCalibrationConfig(yaw_rate_sigma_rad_s=0.005)
    cal = WheelCalibrator.build(_wheel_track(t, v, w, CASES["combined"][0], 0), _imu(t, w, 0), np.eye(4), cfg)
    assert cal is not None
    cal.update(float(t[-1]))

    def qualities() -> tuple[float, float, float, float]:
        cal.cfg = replace(cfg, gyro_yaw_rate_sigma_rad_s=100.0)
        limit, w_small = cal.yaw_quality(), cal.gyro_weight()
        cal.cfg = replace(cfg, gyro_yaw_rate_sigma_rad_s=0.0)
        unblended = cal.yaw_quality()
        cal.cfg, cal.standing_start = cfg, False
        no_start = cal.yaw_quality()
        cal.standing_start = True
        assert 0.0 < w_small < 1e-6
        assert cal.gyro_weight() > 0.5
        return limit, unblended, no_start, cfg.yaw_rate_sigma_rad_s ** 2 / cal.sigma2

    limit, unblended, no_start, rule_before = qualities()
    assert 1.4 < cal.track_factor < 1.8
    assert 0.1 < limit < 0.6  # not clipped
    assert unblended == pytest.approx(limit, rel=1e-6)
    assert no_start == pytest.approx(limit, rel=1e-6)
    assert rule_before < 0.5 * limit  # the rule before: discontinuous by f^2
    cal.theta[0] = 1.0  # f = 1: raw and calibrated wheels are the same, both rules agree
    limit, unblended, no_start, rule_before = qualities()
    assert unblended == pytest.approx(limit, rel=1e-6)
    assert rule_before == pytest.approx(limit, rel=1e-6)


def test_the_gyro_blend_follows_an_applied_imu_offset() -> None:
    """restamp_gyro(shift): the tail's gyro increments are those of the IMU re-stamped by -shift (the
    replay's in-run offset estimate), to 1e-12 rad against a calibrator built on the shifted IMU;
    negative control: without it they are the lagging IMU's."""
    t, v, w = _drive()
    track = _wheel_track(t, v, w, CASES["calibrated"][0], 0)
    imu = _imu(t, w, 0)
    lagged = ImuSeries(imu.stamps + 0.03, imu.acc, imu.gyro, None, "imu")
    moved = WheelCalibrator.build(track, lagged, np.eye(4), WheelCalibrationConfig())
    kept = WheelCalibrator.build(track, lagged, np.eye(4), WheelCalibrationConfig())
    aligned = WheelCalibrator.build(track, imu, np.eye(4), WheelCalibrationConfig())
    assert moved is not None
    assert kept is not None
    assert aligned is not None
    moved.gyro_bias = kept.gyro_bias = aligned.gyro_bias  # the same bias: only the timing differs
    moved.inc_yaw_gyro = kept.inc_yaw_gyro = np.zeros(0)
    moved.restamp_gyro(0.03)
    aligned.restamp_gyro(0.0)
    np.testing.assert_allclose(moved.inc_yaw_gyro, aligned.inc_yaw_gyro, atol=1e-12)
    kept.restamp_gyro(0.0)
    assert np.max(np.abs(kept.inc_yaw_gyro - aligned.inc_yaw_gyro)) > 1e-4


def _mid_drive(err: WheelErrors, seed: int, cfg: WheelCalibrationConfig) -> tuple[WheelCalibrator, np.ndarray,
                                                                                 np.ndarray]:
    """The calibrator on `_drive` begun 8 s in (a log recorded mid-drive: no standing start, the gyro's
    bias unmeasured), consumed to the end; with the drive's stamps and true yaw."""
    t, v, w = _drive(seed=seed)
    true_yaw = np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]
    full, imu = _wheel_track(t, v, w, err, seed), _imu(t, w, seed)
    k, ki = t >= 8.0, imu.stamps >= 8.0
    track = WheelTrack(stamps=full.stamps[k], positions=full.positions[k], quat_xyzw=full.quat_xyzw[k])
    cal = WheelCalibrator.build(track, replace(imu, stamps=imu.stamps[ki], acc=imu.acc[ki], gyro=imu.gyro[ki]),
                                np.eye(4), cfg)
    assert cal is not None
    cal.update(float(t[-1]))
    return cal, t, true_yaw


def _heading_error_deg(track: WheelTrack, t: np.ndarray, true_yaw: np.ndarray) -> float:
    yaw = np.unwrap(Rotation.from_quat(track.quat_xyzw).as_euler("ZYX")[:, 0])
    ref = np.interp(track.stamps, t, true_yaw)
    return float(np.degrees(np.max(np.abs((yaw - yaw[0]) - (ref - ref[0])))))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_without_a_standing_start_the_offset_c_stays_out_of_the_wheels_yaw(seed: int) -> None:
    """Begun mid-drive, the fitted yaw-rate offset c is the gyro's unmeasured bias (c = -f x bias):
    track() leaves it out. The L/R term a v soaks up most of the bias at these nearly constant speeds
    (the confound the standing start breaks), so the heading error stays large (13-20 deg over 32 s
    with a 12 mrad/s bias) but is 2.1-7.5 deg below the rule before (c subtracted, the wheels' yaw
    alone: the negative control, 21.0-21.7 deg); both with calibrated-class wheels."""
    err = CASES["calibrated"][0]
    cal, t, true_yaw = _mid_drive(err, seed, WheelCalibrationConfig())
    assert not cal.standing_start
    assert cal.gyro_weight() == 0.0
    assert cal.theta[2] < -0.001  # c took part of the +12 mrad/s bias (-1.3..-4.6 mrad/s measured)
    after = _heading_error_deg(cal.track(), t, true_yaw)
    before, _, _ = _mid_drive(err, seed, WheelCalibrationConfig(gyro_yaw_rate_sigma_rad_s=0.0))
    before.standing_start = True  # c subtracted, gyro weight 0: the rule before on a log without one
    assert after < _heading_error_deg(before.track(), t, true_yaw) - 1.0


def _begun_mid_drive(w_const: float, cfg: WheelCalibrationConfig, seed: int = 0) -> tuple[WheelCalibrator, np.ndarray,
                                                                                            np.ndarray]:
    """A 40 s drive at 1 m/s with a constant yaw rate w_const (0: a straight line, else an arc or
    circle) begun 3 s in (no standing start), calibrated-class wheels, the gyro's +12 mrad/s bias;
    the calibrator consumed to the end, with the drive's stamps and true yaw."""
    t = np.arange(0.0, 40.0, 0.02)
    v, w = np.clip(t / 2.0, 0.0, 1.0), np.full(t.size, w_const) * np.clip(t / 2.0, 0.0, 1.0)
    full, imu = _wheel_track(t, v, w, CASES["calibrated"][0], seed), _imu(t, w, seed)
    k, ki = t >= 3.0, imu.stamps >= 3.0
    track = WheelTrack(stamps=full.stamps[k], positions=full.positions[k], quat_xyzw=full.quat_xyzw[k])
    cal = WheelCalibrator.build(track, replace(imu, stamps=imu.stamps[ki], acc=imu.acc[ki], gyro=imu.gyro[ki]),
                                np.eye(4), cfg)
    assert cal is not None
    assert not cal.standing_start
    for tk in np.arange(3.2, 40.0, 0.2):  # as the replay does, sweep by sweep
        cal.update(float(tk))
    return cal, t, np.r_[0.0, np.cumsum(w[:-1] * np.diff(t))]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_straight_stretch_gives_the_gyro_bias_without_a_standing_start(seed: int) -> None:
    """Begun mid-drive on a straight line, the gyro's mean over the first 4 s straight stretch is its
    bias (measured within 0.17 mrad/s of 12, seeds 0-2): it arrives 4.2 s after the log's start, the
    gyro is then blended (weight 0.98), and the heading error over the drive is 0.06-0.24 deg against
    24-26 deg without it (straight_bias_window_s=0, the negative control: weight 0, the wheels' yaw
    with the bias in a v)."""
    cal, t, true_yaw = _begun_mid_drive(0.0, WheelCalibrationConfig(), seed)
    assert cal.gyro_bias_source == "straight drive"
    assert abs(cal.gyro_bias - GYRO_BIAS) < 0.00035
    assert cal.gyro_bias_t is not None
    assert cal.gyro_bias_t - 3.0 < 8.0
    assert cal.gyro_weight() > 0.5
    health = wheel_health(cal)
    assert health["gyro_bias_source"] == "straight drive"
    assert health["gyro_bias_sigma_rad_s"] >= 0.002
    off, _, _ = _begun_mid_drive(0.0, WheelCalibrationConfig(straight_bias_window_s=0.0), seed)
    assert off.gyro_weight() == 0.0
    assert wheel_health(off)["gyro_bias_source"] == "none"
    err_on = _heading_error_deg(cal.track(), t, true_yaw)
    assert err_on < 0.5
    assert _heading_error_deg(off.track(), t, true_yaw) > 12.0


@pytest.mark.parametrize("w_const", [0.05, -0.1, 0.3])
def test_a_circle_is_not_taken_for_a_straight_stretch(w_const: float) -> None:
    """On a constant-curvature arc or circle the gyro's mean is the turn rate plus the bias: the
    wheels' turn fails the guard, no bias is taken and the gyro stays out. Negative control: with
    the guards opened the same check takes the turn rate for the bias (off by w_const to 0.2 mrad/s)."""
    cal, _, _ = _begun_mid_drive(w_const, WheelCalibrationConfig())
    assert cal.gyro_bias_source == "none"
    assert cal.gyro_weight() == 0.0
    wide = WheelCalibrationConfig(straight_max_yaw_rate_rad_s=1.0, straight_max_gyro_spread_rad_s=1.0)
    fooled, _, _ = _begun_mid_drive(w_const, wide)
    assert fooled.gyro_bias_source == "straight drive"
    assert abs(fooled.gyro_bias - GYRO_BIAS) > 0.8 * abs(w_const)


def test_wheel_health_names_a_gnss_scale_and_says_it_was_not_used() -> None:
    """Without LiDAR distance steps (bare ground) the scale comes from the fixes after the run
    (slam/wheel_gnss_scale.py): a significant 2 % is flagged and its reason says the run did not use it;
    a 0.3 % one is reported and not flagged; without one the source is the prior (0 +- 5 %)."""
    from mrnc_eval.slam.wheel_gnss_scale import GnssScale

    cal = _calibrate(CASES["exact"][0])
    assert cal.scale_fit is None or cal.scale_fit.steps == 0  # no LiDAR step fed here
    bad = wheel_health(cal, GnssScale(scale=1.02, sigma=0.002, fixes=200, span_m=12.0))
    assert bad["scale_source"] == "gnss"
    assert bad["scale_error"] == pytest.approx(0.02)
    assert bad["verdict"] == "miscalibrated"
    assert any("scale error +2.00 %" in r and "did not use it" in r for r in bad["reasons"])
    fine = wheel_health(cal, GnssScale(scale=1.003, sigma=0.002, fixes=200, span_m=12.0))
    assert fine["verdict"] == "ok"
    prior = wheel_health(cal)
    assert prior["scale_source"] == "prior"
    assert prior["scale_error"] == 0.0
