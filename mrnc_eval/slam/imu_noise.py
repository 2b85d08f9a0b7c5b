"""The IMU as the machine has it: noise and biases measured from the log's stationary stretches
(the machine standing, engine running), for the preintegration (graph #2) instead of fixed
datasheet-class defaults.

Stationary: consecutive windows of `window_s` whose mean gyro and mean specific force stay put
(an engine's vibration averages out within a window; any driving, turning or rocking moves the
means) and whose mean specific force has gravity's magnitude; stretches of at least `min_s`.

What a stationary stretch gives (IMU axes):
- gyro bias: the mean rate (the earth's 7e-5 rad/s is below what is resolved);
- accelerometer bias along gravity: |mean specific force| - g. The other two components cannot be
  told from a tilt with a 6-axis IMU and are not estimated;
- noise densities at the time scale of the preintegration: the Allan deviation sigma(tau) of
  non-overlapping tau-averages times sqrt(tau) (for white noise, the density itself), over
  tau/2..2 tau. Vibration at tens of Hz inflates the per-sample spread (0.5 m/s^2) but mostly
  averages out over a sweep interval; what the ImuFactor integrates is this effective density,
  not the per-sample one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, kw_only=True)
class ImuNoiseEstimate:
    """Noise and biases from the stationary stretches (IMU axes, SI units)."""

    stationary_s: float  # total length of the stationary stretches used, s
    stretches: int
    rate_hz: float
    acc_noise_density: float  # effective white-noise density at tau_s, m/s^2/sqrt(Hz)
    gyro_noise_density: float  # rad/s/sqrt(Hz)
    acc_sample_std: float  # per-sample spread about the stretch mean (vibration included), m/s^2
    gyro_sample_std: float  # rad/s
    gyro_bias: np.ndarray  # (3,) rad/s
    gyro_bias_sigma: float  # standard error of each gyro bias component, rad/s
    acc_bias_along_gravity: float  # |mean specific force| - g, m/s^2
    tau_s: float

    def summary(self) -> dict[str, object]:
        return {"stationary_s": round(self.stationary_s, 3), "stretches": self.stretches,
                "acc_noise_density": self.acc_noise_density, "gyro_noise_density": self.gyro_noise_density,
                "acc_sample_std": self.acc_sample_std, "gyro_sample_std": self.gyro_sample_std,
                "gyro_bias": [float(v) for v in self.gyro_bias], "gyro_bias_sigma": self.gyro_bias_sigma,
                "acc_bias_along_gravity": self.acc_bias_along_gravity, "tau_s": self.tau_s}


def stationary_mask(stamps: np.ndarray, acc: np.ndarray, gyro: np.ndarray, *, gravity: float,
                    window_s: float = 0.5, min_s: float = 1.5, max_gyro_step: float = 0.003,
                    max_acc_step: float = 0.05, max_gravity_error: float = 0.3) -> np.ndarray:
    """(N,) True for samples in stationary stretches: consecutive `window_s` windows whose mean gyro
    (rad/s) and mean specific force (m/s^2) differ by less than max_gyro_step / max_acc_step per axis
    from both neighbours, with | |mean f| - g | < max_gravity_error, in runs of at least `min_s`."""
    n = stamps.size
    out = np.zeros(n, bool)
    if n < 3:
        return out
    win, count, (mg, ma) = _window_means(stamps, window_s, gyro, acc)
    n_win = count.size
    full = count >= 0.8 * np.median(count)
    still = full & (np.abs(np.linalg.norm(ma, axis=1) - gravity) < max_gravity_error)
    step_ok = np.ones(n_win, bool)
    dg, da = np.abs(np.diff(mg, axis=0)).max(axis=1), np.abs(np.diff(ma, axis=0)).max(axis=1)
    calm = (dg < max_gyro_step) & (da < max_acc_step)  # between window k and k+1
    step_ok[:-1] &= calm
    step_ok[1:] &= calm
    still &= step_ok
    # runs of consecutive still windows, at least min_s long
    keep = np.zeros(n_win, bool)
    k = 0
    while k < n_win:
        if not still[k]:
            k += 1
            continue
        j = k
        while j + 1 < n_win and still[j + 1]:
            j += 1
        if (j - k + 1) * window_s >= min_s:
            keep[k:j + 1] = True
        k = j + 1
    return np.asarray(keep[win], bool)


def _window_means(stamps: np.ndarray, width_s: float, *series: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Each sample's window (`width_s` wide from the first stamp), the samples per window, and each
    (N, 3) series' mean per window (NaN where a window is empty)."""
    win = np.floor((stamps - stamps[0]) / width_s).astype(np.int64)
    n = int(win[-1]) + 1
    count = np.bincount(win, minlength=n).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = [np.column_stack([np.bincount(win, x[:, a], n) for a in range(3)]) / count[:, None] for x in series]
    return win, count, means


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of `mask`."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def allan_density(x: np.ndarray, rate_hz: float, tau_s: float) -> float:
    """The white-noise density (per axis, mean over axes) that gives the same spread of averages
    as (N, 3) samples: Allan variance times tau, averaged over every whole number of samples in
    [tau_s / 2, 2 tau_s] (one tau alone can be blind: 0.1 s holds whole periods of 30 and 40 Hz
    vibration, which then cancels exactly, though an interval of another length keeps some).
    NaN when fewer than 3 averages of the longest length fit."""
    lo, hi = max(int(round(0.5 * tau_s * rate_hz)), 1), max(int(round(2.0 * tau_s * rate_hz)), 1)
    if x.shape[0] // hi < 3:
        return float("nan")
    dens = []
    for m in range(lo, hi + 1):
        k = x.shape[0] // m
        means = x[: k * m].reshape(k, m, -1).mean(axis=1)
        dens.append(0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0) * (m / rate_hz))
    return float(np.mean(np.sqrt(np.mean(dens, axis=0))))


def estimate_imu_noise(stamps: np.ndarray, acc: np.ndarray, gyro: np.ndarray, *, gravity: float,
                       tau_s: float = 0.1, min_s: float = 1.5) -> ImuNoiseEstimate | None:
    """Noise densities and biases from the stationary stretches of an IMU log (stamps s, acc
    m/s^2, gyro rad/s, IMU axes); None without a stationary stretch of at least min_s."""
    mask = stationary_mask(stamps, acc, gyro, gravity=gravity, min_s=min_s)
    runs = [(a, b) for a, b in _runs(mask) if b - a >= 3]
    if not runs:
        return None
    rate = 1.0 / float(np.median(np.diff(stamps)))
    # per stretch: remove its own mean (bias) before pooling, so stretches with different biases
    # (a bias walk between them) do not look like noise
    acc_res = np.vstack([acc[a:b] - acc[a:b].mean(axis=0) for a, b in runs])
    gyro_res = np.vstack([gyro[a:b] - gyro[a:b].mean(axis=0) for a, b in runs])
    weights = np.array([b - a for a, b in runs], float)
    acc_d = np.nanmean([allan_density(acc[a:b], rate, tau_s) for a, b in runs])
    gyro_d = np.nanmean([allan_density(gyro[a:b], rate, tau_s) for a, b in runs])
    if not (np.isfinite(acc_d) and np.isfinite(gyro_d)):
        return None
    gyro_bias = np.average([gyro[a:b].mean(axis=0) for a, b in runs], axis=0, weights=weights)
    f = np.average([acc[a:b].mean(axis=0) for a, b in runs], axis=0, weights=weights)
    total = float(weights.sum())
    return ImuNoiseEstimate(stationary_s=total / rate, stretches=len(runs), rate_hz=rate,
                            acc_noise_density=float(acc_d), gyro_noise_density=float(gyro_d),
                            acc_sample_std=float(acc_res.std(axis=0).mean()),
                            gyro_sample_std=float(gyro_res.std(axis=0).mean()),
                            gyro_bias=np.asarray(gyro_bias, np.float64),
                            # the tau-average spread, over the number of tau-windows
                            gyro_bias_sigma=float(gyro_d / np.sqrt(total / rate)),
                            acc_bias_along_gravity=float(np.linalg.norm(f) - gravity), tau_s=tau_s)


@dataclass(frozen=True, kw_only=True)
class StandingStartBias:
    """The gyro's bias from a standing start too short for the noise (IMU axes)."""

    gyro_bias: np.ndarray  # (3,) rad/s
    sigma: float  # standard error of each component, rad/s
    duration_s: float  # the standing stretch at the log's start, s

    def summary(self) -> dict[str, object]:
        return {"gyro_bias": [float(v) for v in self.gyro_bias], "gyro_bias_sigma": self.sigma,
                "duration_s": round(self.duration_s, 3)}


def standing_start_bias(stamps: np.ndarray, acc: np.ndarray, gyro: np.ndarray, *, min_s: float, max_rate: float,
                        block_s: float = 0.1, max_gyro_step: float = 0.005) -> StandingStartBias | None:
    """The mean gyro (rad/s) over the log's first stretch of `block_s` blocks whose means stay within
    max_gyro_step per axis of the mean of the blocks before them: the machine has not started to turn
    or pitch yet (engine vibration mostly averages out within a block: its remainder, 0.002-0.003
    rad/s with 9-11 samples a block, sets the step; the specific force does not tell: a heavy machine
    moves off with a slow ramp of acceleration from the first sample, and the vibration's remainder
    in a block is 0.05 m/s^2). Without wheels on bare ground the heading is the gyro's, and it drifts
    with the whole turn-on bias (field IMU: 0.01 rad/s, 1 deg/s of the open loop's heading) when the
    start is shorter than the noise estimate's stationary_min_s. None when that stretch is shorter
    than min_s (s) or its rate about the vertical (the mean specific force's axis, `acc` m/s^2) exceeds
    max_rate (rad/s): a log begun mid-turn (a steady rate about a level axis is no turn: a stress IMU
    with a 0.044 rad/s roll-axis offset and a 0.014 rad/s yaw-axis one was refused for its roll axis).
    The sigma is the spread of the block means over the square root of their number."""
    if stamps.size < 3:
        return None
    block, count, (mg,) = _window_means(stamps, block_s, gyro)
    n = count.size
    k = 1  # the first block that turned: its mean off the mean of the blocks before it
    while k < n and count[k] > 0 and np.abs(mg[k] - mg[:k].mean(axis=0)).max() < max_gyro_step:
        k += 1
    if k * block_s < min_s or k < 2:
        return None
    bias = gyro[block < k].mean(axis=0)
    up = acc[block < k].mean(axis=0)
    if abs(float(bias @ up)) > max_rate * float(np.linalg.norm(up)):
        return None
    sigma = float(np.sqrt(np.mean(mg[:k].var(axis=0, ddof=1)) / k))
    return StandingStartBias(gyro_bias=np.asarray(bias, np.float64), sigma=sigma, duration_s=k * block_s)
