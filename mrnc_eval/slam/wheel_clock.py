"""wheel_clock: the wheel odometry's stamp offset against the gyro's, from the log's turns.

A skid-steer's wheel odometry is often stamped by a host or PLC bridge tens of milliseconds after the
motion it measures, while the IMU-LiDAR offset is small and estimated elsewhere (slam/time_offset.py).
A late wheel clock puts every wheel yaw and distance step where the gyro and the LiDAR say the machine
did something else: on the simulated 20 m loop 100 ms late doubled the online APE and read as a
miscalibrated L/R mismatch.

Both sensors see the same yaw rate up to the skid (track factor f), the L/R mismatch (a yaw rate
proportional to speed) and an offset, so for each candidate lag tau the wheels' yaw rate is regressed
on the gyro's yaw rate shifted by tau, the wheels' speed and a constant (window-averaged rates from the
cumulative angles: pickup noise averages down, no derivative is taken); the lag with the least squared
residual is the estimate (parabolic between grid points). Its standard error is a delete-one-block
jackknife over time blocks (the fit's residuals with a block left out, not refitted: cheap, and the
regression's three coefficients barely move with one block of eight). Only changes of yaw rate carry
the lag: on a straight line, or a circle at constant speed, the error is large and the verdict says so."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrnc_eval.slam.config import WheelClockConfig
from mrnc_eval.slam.jackknife import jackknife_sigma


@dataclass(kw_only=True)
class WheelClock:
    offset_s: float  # wheel stamps minus the gyro's for the same motion (positive: wheels stamped late), s
    sigma_s: float  # jackknife standard error, s
    samples: int  # grid points used
    verdict: str = "not measurable"  # "ok", "late" / "early" (flagged), or "not measurable"
    applied_s: float = 0.0  # subtracted from the wheel stamps for the run, s (0: not applied)
    reasons: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, object]:
        return {"offset_s": self.offset_s, "sigma_s": self.sigma_s, "samples": self.samples,
                "verdict": self.verdict, "applied_s": self.applied_s, "reasons": list(self.reasons)}


def wheel_clock(wheel_t: np.ndarray, wheel_yaw: np.ndarray, wheel_dist: np.ndarray, gyro_t: np.ndarray,
                gyro_yaw_rate: np.ndarray, cfg: WheelClockConfig) -> WheelClock:
    """The wheel stamps' offset against the gyro's. `wheel_t` (N,) ascending s; `wheel_yaw` and
    `wheel_dist` (N,) the wheels' cumulative yaw (rad, unwrapped) and forward distance (m) at them;
    `gyro_t` (M,) ascending s and `gyro_yaw_rate` (M,) rad/s about base_link z."""
    grid = _grid(wheel_t, gyro_t, cfg)
    if grid.size < 4 * cfg.blocks:
        return WheelClock(offset_s=float("nan"), sigma_s=float("nan"), samples=int(grid.size),
                          reasons=[f"{grid.size} samples where wheels and gyro overlap: too few"])
    rss, factor, lags = _residuals(grid, (wheel_t, wheel_yaw, wheel_dist),
                                   (gyro_t, _cumulative(gyro_t, gyro_yaw_rate)), cfg)
    offset = _argmin(rss.sum(axis=1), lags)
    sigma = jackknife_sigma(np.array([_argmin(rss.sum(axis=1) - rss[:, j], lags) for j in range(cfg.blocks)]))
    out = WheelClock(offset_s=offset, sigma_s=sigma, samples=int(grid.size), verdict="ok")
    best = int(np.argmin(rss.sum(axis=1)))
    f = float(factor[best])
    if not cfg.min_track_factor <= f <= 1.0 / cfg.min_track_factor:  # NaN too
        # wheels that do not turn with the gyro (a frozen pose, another machine's topic) time nothing:
        # every lag fits them equally, and a jackknife over equal costs reads 0 s
        out.verdict = "not measurable"
        out.reasons = [f"the wheels' yaw follows the gyro's by a factor of {f:.2f}: nothing to time them by"]
    elif best in (0, lags.size - 1):  # the least residual at the edge: the offset may lie beyond the search
        out.verdict = "not measurable"
        out.reasons = [f"the best fit is at the edge of the searched +-{cfg.max_lag_s:g} s (slam.wheel_odom.clock."
                       "max_lag_s): the offset may be larger"]
    elif not sigma <= cfg.max_sigma_s:  # NaN too
        out.verdict = "not measurable"
        out.reasons = [f"standard error {sigma * 1e3:.0f} ms: too few changes of yaw rate to time the wheels by"]
    elif abs(offset) > cfg.flag_s and abs(offset) > cfg.flag_sigmas * sigma:
        out.verdict = "late" if offset > 0 else "early"
        out.reasons = [f"wheel stamps {offset * 1e3:+.0f} +- {sigma * 1e3:.0f} ms against the gyro's"]
    return out


def _grid(wheel_t: np.ndarray, gyro_t: np.ndarray, cfg: WheelClockConfig) -> np.ndarray:
    """Sample times where both streams cover every candidate lag's window, s."""
    if wheel_t.size < 3 or gyro_t.size < 3:
        return np.zeros(0)
    margin = cfg.max_lag_s + cfg.window_s
    t0, t1 = max(wheel_t[0], gyro_t[0]) + margin, min(wheel_t[-1], gyro_t[-1]) - margin
    return np.arange(t0, t1, cfg.grid_s) if t1 > t0 else np.zeros(0)


def _cumulative(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Trapezoid integral of `rate` at the stamps `t`."""
    return np.asarray(np.r_[0.0, np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))], float)


def _rate(t: np.ndarray, stamps: np.ndarray, cumulative: np.ndarray, window_s: float) -> np.ndarray:
    """Mean rate over window_s centred on each t, from a cumulative quantity."""
    h = 0.5 * window_s
    return np.asarray((np.interp(t + h, stamps, cumulative) - np.interp(t - h, stamps, cumulative)) / window_s, float)


def _residuals(t: np.ndarray, wheel: tuple[np.ndarray, np.ndarray, np.ndarray], gyro: tuple[np.ndarray, np.ndarray],
               cfg: WheelClockConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per candidate lag and time block, the squared residual of the wheels' yaw rate regressed on
    [gyro yaw rate at t - lag, wheel speed, 1]; per lag the gyro's coefficient (the track factor); and
    the lags (s)."""
    wt, wyaw, wdist = wheel
    y = _rate(t, wt, wyaw, cfg.window_s)
    speed = _rate(t, wt, wdist, cfg.window_s)
    lags = np.arange(-cfg.max_lag_s, cfg.max_lag_s + 0.5 * cfg.lag_step_s, cfg.lag_step_s)
    block = np.repeat(np.arange(cfg.blocks), [p.size for p in np.array_split(np.arange(t.size), cfg.blocks)])
    rss, factor = np.zeros((lags.size, cfg.blocks)), np.zeros(lags.size)
    for i, lag in enumerate(lags):
        x = np.c_[_rate(t - lag, gyro[0], gyro[1], cfg.window_s), speed, np.ones(t.size)]
        theta = np.linalg.lstsq(x, y, rcond=None)[0]
        rss[i] = np.bincount(block, weights=(y - x @ theta) ** 2, minlength=cfg.blocks)
        factor[i] = theta[0]
    return rss, factor, lags


def _argmin(cost: np.ndarray, lags: np.ndarray) -> float:
    """The lag of least cost, refined by a parabola through the grid minimum and its neighbours, s."""
    k = int(np.clip(np.argmin(cost), 1, cost.size - 2))
    a, b, c = cost[k - 1], cost[k], cost[k + 1]
    curvature = a - 2.0 * b + c
    step = float(lags[1] - lags[0])
    shift = 0.5 * step * (a - c) / curvature if curvature > 0 else 0.0
    return float(lags[k] + np.clip(shift, -step, step))
