"""The ground check of the mount (slam/ground_mount.py) on synthetic first sweeps: a LiDAR whose true
mount is the written one turned by a known error sees level ground around a level machine tilted by
that error in the written base frame; rough, bent or overgrown ground must say "not measurable"."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.commands.slam import corrected_mount
from mrnc_eval.slam.config import GroundMountConfig
from mrnc_eval.slam.ground_mount import ground_mount

BASE_HEIGHT_M = 0.6  # base_link above the ground, as the simulator's
# the written base_link -> LiDAR mount: 1.9 m up, yawed 90 deg so that LiDAR and base axes differ
WRITTEN = np.eye(4)
WRITTEN[:3, :3] = Rotation.from_euler("z", 90.0, degrees=True).as_matrix()
WRITTEN[:3, 3] = (1.2, 0.0, 1.9)


def _height(kind: str, x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Ground height (m, true base frame) of the kinds of ground the tests drive on."""
    z = np.full_like(x, -BASE_HEIGHT_M)
    if kind == "waves":  # the simulated field terrain's fine roughness: 0.04 m at 2.7-3.7 m
        z += 0.04 * np.sin(1.7 * x + 0.3) * np.sin(2.3 * y + 1.0)
    if kind == "ramp":  # a 5 % rise starting 5 m ahead
        z += 0.05 * np.clip(x - 5.0, 0.0, None)
    if kind == "bushes":  # half the returns off leaves up to 0.6 m above the ground
        z += np.where(rng.random(x.size) < 0.5, rng.uniform(0.0, 0.6, x.size), 0.0)
    if kind == "grass":  # every return off grass 0.1-0.5 m tall: no ground seen
        z += rng.uniform(0.1, 0.5, x.size)
    return z


def _first_sweeps(error_rpy_deg: tuple[float, float, float], *, kind: str = "level", seed: int = 0,
                  written: np.ndarray = WRITTEN) -> np.ndarray:
    """Five sweeps' ground returns (32 beams down to -45 deg, 512 columns, 1 cm range noise) in the
    written base frame, the LiDAR really sitting at written x error (true relative to written, LiDAR axes)."""
    rng = np.random.default_rng(seed)
    true = written.copy()
    true[:3, :3] = written[:3, :3] @ Rotation.from_euler("xyz", error_rpy_deg, degrees=True).as_matrix()
    elev = np.radians(np.linspace(-45.0, -10.0, 14))
    az = np.radians(np.arange(512) * 360.0 / 512)
    el, a = np.meshgrid(elev, az)
    rays_s = np.stack([np.cos(el) * np.cos(a), np.cos(el) * np.sin(a), np.sin(el)], axis=-1).reshape(-1, 3)
    rays_b = rays_s @ true[:3, :3].T
    origin = true[:3, 3]
    clouds = []
    for _ in range(5):
        rng_m = np.full(rays_b.shape[0], 5.0)
        for _ in range(20):  # fixed-point intersection with the height field
            hit = origin + rays_b * rng_m[:, None]
            rng_m = (_height(kind, hit[:, 0], hit[:, 1], rng) - origin[2]) / rays_b[:, 2]
        rng_m = rng_m + rng.normal(0.0, 0.01, rng_m.size)
        keep = (rng_m > 0) & (rng_m < 30.0)
        p_sensor = rays_s[keep] * rng_m[keep, None]
        clouds.append(p_sensor @ written[:3, :3].T + written[:3, 3])
    return np.vstack(clouds)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_known_roll_and_pitch_error_is_recovered_and_flagged(seed: int) -> None:
    g = ground_mount(_first_sweeps((0.3, -0.4, 0.5), seed=seed), WRITTEN[:3, :3], GroundMountConfig())
    assert g.verdict == "misaligned"
    # measured: the correction within 0.005 deg of (0.3, -0.4) in LiDAR axes at sigma ~0.03 deg
    assert g.correction_rpy_deg[0] == pytest.approx(0.3, abs=0.03)
    assert g.correction_rpy_deg[1] == pytest.approx(-0.4, abs=0.03)
    assert g.correction_rpy_deg[2] == pytest.approx(0.0, abs=0.01)  # yaw is not seen from the ground
    # base axes: the LiDAR's x is the base's y (the 90 deg yaw), so base roll = -LiDAR pitch
    assert g.roll_deg == pytest.approx(0.4, abs=0.03)
    assert g.pitch_deg == pytest.approx(0.3, abs=0.03)
    assert max(g.roll_sigma_deg, g.pitch_sigma_deg) < 0.1


def test_the_correction_applied_reads_level() -> None:
    """corrected_mount with the finding in place of /tf_static's mount: the same ground reads ~0."""
    pts = _first_sweeps((0.3, -0.4, 0.5))
    g = ground_mount(pts, WRITTEN[:3, :3], GroundMountConfig())
    fixed = corrected_mount(WRITTEN, g.correction_rpy_deg)
    sensor = (pts - WRITTEN[:3, 3]) @ WRITTEN[:3, :3]
    again = ground_mount(sensor @ fixed[:3, :3].T + fixed[:3, 3], fixed[:3, :3], GroundMountConfig())
    assert again.verdict == "ok"
    assert abs(again.roll_deg) < 0.02
    assert abs(again.pitch_deg) < 0.02


def test_a_right_mount_reads_level_and_is_left_alone() -> None:
    """Negative control: the written mount is the true one."""
    g = ground_mount(_first_sweeps((0.0, 0.0, 0.0)), WRITTEN[:3, :3], GroundMountConfig())
    assert g.verdict == "ok"
    assert abs(g.roll_deg) < 0.03
    assert abs(g.pitch_deg) < 0.03
    assert g.correction_rpy_deg == (0.0, 0.0, 0.0)


def test_a_wall_in_the_ring_does_not_tilt_the_plane() -> None:
    pts = _first_sweeps((0.3, -0.4, 0.0))
    wall = np.stack([np.full(3000, 5.0), np.linspace(-4.0, 4.0, 3000), np.tile(np.linspace(-0.6, 2.0, 30), 100)],
                    axis=1)
    g = ground_mount(np.vstack([pts, wall]), WRITTEN[:3, :3], GroundMountConfig())
    assert g.verdict == "misaligned"
    assert g.correction_rpy_deg[1] == pytest.approx(-0.4, abs=0.03)


@pytest.mark.parametrize(("kind", "error"), [("waves", (0.3, -0.4, 0.5)), ("grass", (0.3, -0.4, 0.5)),
                                             ("ramp", (0.4, 0.0, 0.0))])
def test_ground_that_is_not_the_footprints_plane_is_not_measurable(kind: str, error: tuple[float, float, float]
                                                                   ) -> None:
    """The field terrain's short waves (several degrees of slope under the wheels), tall grass, and a
    slope change ahead for a base pitch error (LiDAR roll, the 90 deg yaw): no reading, no correction."""
    g = ground_mount(_first_sweeps(error, kind=kind), WRITTEN[:3, :3], GroundMountConfig())
    assert g.verdict == "not measurable", g.reasons
    assert g.correction_rpy_deg == (0.0, 0.0, 0.0)
    assert g.reasons


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bushes_over_half_the_ring_do_not_tilt_the_plane(seed: int) -> None:
    """The fit starts on the lower half of the heights and keeps the returns near the plane: the reading
    stays right (measured within 0.001 deg), while the low leaves inside the cut raise the slope spread
    to the gate (sigma 0.11-0.17 deg): flagged or not measurable, never a wrong correction."""
    g = ground_mount(_first_sweeps((0.3, -0.4, 0.5), kind="bushes", seed=seed), WRITTEN[:3, :3], GroundMountConfig())
    assert g.roll_deg == pytest.approx(0.4, abs=0.03)
    assert g.pitch_deg == pytest.approx(0.3, abs=0.03)
    assert g.verdict in ("misaligned", "not measurable")
    for got, true in zip(g.correction_rpy_deg[:2], (0.3, -0.4), strict=True):
        assert got == pytest.approx(0.0, abs=1e-9) or got == pytest.approx(true, abs=0.03)


def test_a_ramp_ahead_leaves_the_roll_readable() -> None:
    """The slope change along x hides the pitch only: a base roll error (LiDAR pitch) is still read."""
    g = ground_mount(_first_sweeps((0.0, 0.4, 0.0), kind="ramp"), WRITTEN[:3, :3], GroundMountConfig())
    assert g.verdict == "misaligned"
    assert g.correction_rpy_deg[1] == pytest.approx(0.4, abs=0.03)
    assert g.correction_rpy_deg[0] == pytest.approx(0.0, abs=1e-9)
    assert any("pitch not measurable" in r for r in g.reasons)


def test_too_few_points_is_not_measurable() -> None:
    g = ground_mount(np.zeros((10, 3)), np.eye(3), GroundMountConfig())
    assert g.verdict == "not measurable"
    assert "too few" in g.reasons[0]
