"""wheel_health: what the online calibration found about the wheel odometry, and a verdict.

"ok": the wheels agree with the gyro (and the LiDAR) within the flag limits; "miscalibrated": an
estimate is significantly off (L/R mismatch, effective track factor, scale), the SLAM used the
calibrated wheels, and the values are what the odometry node should be given; "unreliable":
significantly more than flag_rejected_fraction of the increments failed the gate (by flag_sigmas
binomial sigmas at that fraction: early in a drive one slip episode, a burst of a few rejected bins,
is not a fraction of the drive)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mrnc_eval.slam.config import WheelCalibrationConfig
from mrnc_eval.slam.wheel_calibration import WheelCalibrator
from mrnc_eval.slam.wheel_gnss_scale import GnssScale


def wheel_health(cal: WheelCalibrator, gnss_scale: GnssScale | None = None) -> dict[str, Any]:
    """The estimates with their 1-sigma, innovation statistics, rejected fraction and the verdict. The
    scale is the LiDAR steps' (the one the run used); without any, `gnss_scale`'s (read after the run
    against the fixes, reported only), else the prior's."""
    cfg = cal.cfg
    cov = cal.covariance
    lr, lr_sigma = cal.lr_mismatch()
    fit = cal.scale_fit
    scale, scale_sigma, source = cal.scale, fit.sigma if fit is not None else cal.cfg.scale_prior_sigma, "lidar"
    if fit is None or fit.steps == 0:
        scale, scale_sigma, source = (1.0, scale_sigma, "prior") if gnss_scale is None \
            else (gnss_scale.scale, gnss_scale.sigma, "gnss")
    res = np.asarray(cal.res, float)
    raw = np.asarray(cal.raw_res, float)
    rejected = cal.n_rejected / cal.n_bins if cal.n_bins else 0.0
    est = {"track_factor": cal.track_factor, "track_factor_sigma": float(np.sqrt(cov[0, 0])),
           "lr_mismatch": lr, "lr_mismatch_sigma": lr_sigma,
           "yaw_rate_offset_rad_s": float(cal.theta[2]), "yaw_rate_offset_sigma_rad_s": float(np.sqrt(cov[2, 2])),
           "scale_error": scale - 1.0, "scale_error_sigma": scale_sigma,
           "rejected_fraction_sigma": rejected_sigma(cal.n_bins, cfg)}
    reasons = flags(est, rejected, cfg, scale_source=source)
    unreliable = too_many_rejected(rejected, est["rejected_fraction_sigma"], cfg)
    verdict = "ok" if not reasons else "unreliable" if unreliable else "miscalibrated"
    return {**est, "gyro_bias_at_start_rad_s": cal.gyro_bias if cal.standing_start else 0.0, **gyro_bias_record(cal),
            "bins": cal.n_bins, "rejected_fraction": rejected,
            "innovation_rms_rad_s": float(np.sqrt(np.mean(res ** 2))) if res.size else None,
            "innovation_nis_mean": float(np.mean(cal.nis)) if cal.nis else None,
            "raw_yaw_rate_minus_gyro_rms_rad_s": float(np.sqrt(np.mean(raw ** 2))) if raw.size else None,
            "yaw_hold_scale": cal.yaw_quality(), "scale_source": source,
            "scale_steps": fit.steps if fit is not None else 0,
            "slip_steps": fit.slip_steps if fit is not None else 0,
            "slip_mean_over_read": fit.slip_mean if fit is not None else None,
            "verdict": verdict, "reasons": reasons}


def gyro_bias_record(cal: WheelCalibrator) -> dict[str, Any]:
    """Where the gyro's bias came from ("standing start"; "straight drive": its mean over a straight
    stretch found later, without a standing start; "none": unmeasured, the gyro then not blended),
    its value and 1 sigma (rad/s), and for a late one when it arrived (s after the wheels' first
    sample)."""
    late = cal.gyro_bias_t is not None and not cal.standing_start
    return {"gyro_bias_source": cal.gyro_bias_source,
            "gyro_bias_rad_s": cal.gyro_bias if cal.bias_known else None,
            "gyro_bias_sigma_rad_s": cal.gyro_bias_sigma if cal.bias_known else None,
            "gyro_bias_after_s": float(cal.gyro_bias_t - cal.inc.stamps[0])
            if late and cal.gyro_bias_t is not None else None}


def flags(est: dict[str, float], rejected_fraction: float, cfg: WheelCalibrationConfig, *,
          scale_source: str = "lidar") -> list[str]:
    """Why the wheels disagree: each estimate beyond its limit by more than flag_sigmas sigma, the
    rejected fraction beyond its limit by more than flag_sigmas binomial sigmas. A scale read from
    GNSS after the run says so: the run did not use it."""
    k = cfg.flag_sigmas
    out = []

    def off(value: float, nominal: float, sigma: float, limit: float) -> bool:
        return abs(value - nominal) > limit and abs(value - nominal) > k * sigma

    if off(est["lr_mismatch"], 0.0, est["lr_mismatch_sigma"], cfg.flag_lr_mismatch):
        out.append(f"left/right mismatch {est['lr_mismatch'] * 100:+.2f} % +- {est['lr_mismatch_sigma'] * 100:.2f} %")
    if off(est["track_factor"], 1.0, est["track_factor_sigma"], cfg.flag_track_factor):
        out.append(f"effective track factor {est['track_factor']:.2f} +- {est['track_factor_sigma']:.2f} "
                   "(wheel yaw / gyro yaw)")
    if off(est["scale_error"], 0.0, est["scale_error_sigma"], cfg.flag_scale):
        out.append(f"scale error {est['scale_error'] * 100:+.2f} % +- {est['scale_error_sigma'] * 100:.2f} %"
                   + (" (from the GNSS fixes after the run; the run did not use it)" if scale_source == "gnss" else ""))
    if too_many_rejected(rejected_fraction, est["rejected_fraction_sigma"], cfg):
        out.append(f"{rejected_fraction * 100:.0f} % of the wheel increments failed the gate against the gyro")
    return out


def rejected_sigma(n_bins: int, cfg: WheelCalibrationConfig) -> float:
    """Binomial sigma of the rejected fraction over n_bins bins if the true rate were
    flag_rejected_fraction (bins taken as independent; rejections come in bursts, so this is the
    small end of it)."""
    p = cfg.flag_rejected_fraction
    return float(np.sqrt(p * (1.0 - p) / max(n_bins, 1)))


def too_many_rejected(fraction: float, sigma: float, cfg: WheelCalibrationConfig) -> bool:
    """The rejected fraction is above flag_rejected_fraction by more than flag_sigmas sigma."""
    return fraction - cfg.flag_rejected_fraction > max(cfg.flag_sigmas * sigma, 0.0)
