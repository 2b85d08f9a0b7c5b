"""The accelerometer's unit (slam/imu_units.py, commands/slam.py `_imu_in_si`): a driver writing g
instead of m/s^2 is found from the median |specific force| and scaled; neither unit is an input
error for lio. Negative control: an IMU in m/s^2 is left as it is."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from mrnc_eval.commands.slam import _imu_in_si
from mrnc_eval.config import Config, replace_path
from mrnc_eval.data import ImuSeries
from mrnc_eval.errors import InputError
from mrnc_eval.slam.imu_units import STANDARD_GRAVITY, accelerometer_scale

G = 9.80511  # slam.imu.gravity's default


def _drive_acc(unit: float, seed: int = 0) -> np.ndarray:
    """Specific force of a machine driving over rough ground: gravity, +-0.5 m/s^2 of vibration,
    0.3 m/s^2 of acceleration, tilts of a few degrees; in m/s^2 divided by `unit`."""
    rng = np.random.default_rng(seed)
    n = 4000
    tilt = np.radians(3.0) * rng.standard_normal((n, 2))
    acc = np.c_[G * np.sin(tilt[:, 0]) + 0.3 * rng.standard_normal(n), G * np.sin(tilt[:, 1]),
                G * np.cos(tilt[:, 0]) * np.cos(tilt[:, 1])] + 0.5 * rng.standard_normal((n, 3))
    return acc / unit


def test_an_accelerometer_in_m_s2_is_left_as_it_is() -> None:
    scale, median = accelerometer_scale(_drive_acc(1.0), G)
    assert scale == 1.0
    assert median == pytest.approx(G, rel=0.03)


def test_an_accelerometer_in_g_is_scaled_to_m_s2() -> None:
    scale, median = accelerometer_scale(_drive_acc(STANDARD_GRAVITY), G)
    assert scale == STANDARD_GRAVITY
    assert median == pytest.approx(1.0, rel=0.03)


@pytest.mark.parametrize("unit", [STANDARD_GRAVITY / 1000.0, 1e9])  # mg (median ~1000), an all-but-zero signal
def test_neither_unit_is_refused(unit: float) -> None:
    scale, _ = accelerometer_scale(_drive_acc(unit), G)
    assert scale is None


def test_no_finite_sample_is_refused() -> None:
    assert accelerometer_scale(np.full((10, 3), np.nan), G)[0] is None
    assert accelerometer_scale(np.zeros((0, 3)), G)[0] is None


class _Log:
    roles: ClassVar[dict[str, str]] = {"imu": "/imu"}

    def __init__(self, unit: float) -> None:
        self.unit = unit

    def imu(self) -> ImuSeries:
        acc = _drive_acc(self.unit)
        t = np.arange(acc.shape[0]) * 0.01
        return ImuSeries(t, acc, np.zeros_like(acc), None, "imu")


def test_the_run_reads_the_imu_in_m_s2_and_says_why() -> None:
    imu, note = _imu_in_si(_Log(STANDARD_GRAVITY), Path("x.mcap"), Config())  # type: ignore[arg-type]
    assert np.median(np.linalg.norm(imu.acc, axis=1)) == pytest.approx(G, rel=0.03)
    assert "/imu" in note
    assert "in g" in note
    same, none = _imu_in_si(_Log(1.0), Path("x.mcap"), Config())  # type: ignore[arg-type]
    assert none == ""
    assert np.median(np.linalg.norm(same.acc, axis=1)) == pytest.approx(G, rel=0.03)


def test_an_imu_in_neither_unit_stops_lio_and_is_noted_for_kiss_icp() -> None:
    with pytest.raises(InputError, match="neither") as err:
        _imu_in_si(_Log(STANDARD_GRAVITY / 1000.0), Path("x.mcap"), Config())  # type: ignore[arg-type]
    assert err.value.topic == "/imu"
    kiss = replace_path(Config(), "slam.method", "kiss-icp")
    _, note = _imu_in_si(_Log(STANDARD_GRAVITY / 1000.0), Path("x.mcap"), kiss)  # type: ignore[arg-type]
    assert "kiss-icp" in note
