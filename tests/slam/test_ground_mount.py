"""The ground check of the mount (slam/ground_mount.py) on synthetic first sweeps: a LiDAR whose true
mount is the written one turned by a known error sees level ground around a level machine tilted by
that error in the written base frame; rough, bent or overgrown ground must say "not measurable"."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mrnc_eval.commands.slam import LogInputs, _add_ground_check, applied_mount_rpy, corrected_mount, ground_check
from mrnc_eval.config import Config, replace_paths
from mrnc_eval.data import Sweep
from mrnc_eval.io import open_log
from mrnc_eval.results import RunResult
from mrnc_eval.slam.config import GroundMountConfig
from mrnc_eval.slam.ground_mount import GroundMount, ground_mount

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


# --- the check's bad inputs and its warning (review of the seventh session's merge) ---------------------------


def _log_of(sweeps: list[Sweep]) -> Any:
    """A stand-in for the LogReader: ground_check reads only its sweeps."""
    return SimpleNamespace(sweeps=lambda **_: iter(sweeps))


def _in_sensor_frame(pts: np.ndarray, stamps: list[float]) -> list[Sweep]:
    """`_first_sweeps`' points (written base frame) back in the LiDAR frame, as len(stamps) sweeps."""
    sensor = ((pts - WRITTEN[:3, 3]) @ WRITTEN[:3, :3]).astype(np.float32)
    return [Sweep(stamp=t, points=p) for t, p in zip(stamps, np.array_split(sensor, len(stamps)), strict=True)]


def test_an_empty_sweep_at_the_start_is_skipped_not_a_crash() -> None:
    """A sweep with no returns (a driver starting up; no-return points are removed when read) ahead of
    five good ones: it was sliced with a step of 0 (ValueError, the run stopped before it began). Now it
    is passed over and the good sweeps give the reading; negative control: the good sweeps alone read
    the same."""
    good = _in_sensor_frame(_first_sweeps((0.3, -0.4, 0.5)), [0.1, 0.2, 0.3, 0.4, 0.5])
    empty = Sweep(stamp=0.0, points=np.zeros((0, 3), np.float32))
    g = ground_check(_log_of([empty, *good]), WRITTEN, Config())
    alone = ground_check(_log_of(good), WRITTEN, Config())
    assert g is not None
    assert alone is not None
    assert g.verdict == "misaligned"
    assert g.sweeps == 5
    assert g.correction_rpy_deg == alone.correction_rpy_deg
    assert g.correction_rpy_deg[1] == pytest.approx(-0.4, abs=0.03)
    # a log of empty sweeps is looked at for span_s only, not decoded to its end: the 7th is never asked for
    asked: list[float] = []

    def stream(**_: Any) -> Any:
        for k in range(100):
            asked.append(0.1 * k)
            yield Sweep(stamp=0.1 * k, points=np.zeros((0, 3), np.float32))

    none = ground_check(SimpleNamespace(sweeps=stream), WRITTEN, Config())
    assert none is not None
    assert none.verdict == "not measurable"
    assert none.sweeps == 0
    assert len(asked) == 7  # 0.0-0.5 s, and the one past the span that ends the look


def test_a_ring_without_a_plane_to_fit_is_not_measurable_not_a_crash() -> None:
    """Ground returns all on one line (x only: a plane's y slope undetermined; the same for returns
    repeating one point): the fit's covariance was a singular inverse (LinAlgError stopped the run).
    Now the undetermined axis has an infinite sigma and is not read."""
    rng = np.random.default_rng(0)
    line = np.c_[rng.uniform(3.0, 7.0, 2000), np.zeros(2000), -BASE_HEIGHT_M + rng.normal(0.0, 0.01, 2000)]
    g = ground_mount(line, np.eye(3), GroundMountConfig())
    assert g.verdict == "not measurable"
    assert g.correction_rpy_deg == (0.0, 0.0, 0.0)
    assert not np.isfinite(g.roll_sigma_deg)


def test_a_nearly_empty_sweep_does_not_hide_the_other_sweeps() -> None:
    """Five good sweeps and a sixth of 20 returns (too few cell pairs for a slope of its own): its
    infinite mean square made the whole slope spread infinite (sigma 90 deg, not measurable). Now a
    sweep that cannot say is left out of the mean. Negative control: when no sweep has the pairs (one
    sparse sweep) the spread stays infinite and the check says not measurable."""
    pts = _first_sweeps((0.3, -0.4, 0.5))
    labels = np.repeat(np.arange(5), -(-pts.shape[0] // 5))[:pts.shape[0]]
    g = ground_mount(np.vstack([pts, pts[:20]]), WRITTEN[:3, :3], GroundMountConfig(), sweep=np.r_[labels, [5] * 20])
    assert g.verdict == "misaligned"
    assert max(g.slope_spread_deg) < 0.05
    assert g.correction_rpy_deg[1] == pytest.approx(-0.4, abs=0.03)
    # one sweep, two returns a 0.5 m cell (a cell mean needs 3): plenty for the plane, no slope of its own
    centres = np.mgrid[-7.75:8.0:0.5, -7.75:8.0:0.5].reshape(2, -1).T
    xy = np.vstack([centres, centres + 0.1])
    xy = xy[(np.hypot(xy[:, 0], xy[:, 1]) >= 2.0) & (np.hypot(xy[:, 0], xy[:, 1]) <= 8.0)]
    s = ground_mount(np.c_[xy, -BASE_HEIGHT_M + 0.005 * xy[:, 0]], WRITTEN[:3, :3], GroundMountConfig())
    assert s.points >= 500  # enough for the fit: only the slope spread cannot be had
    assert s.verdict == "not measurable"
    assert s.slope_spread_deg == (90.0, 90.0)  # arctan of an infinite slope: none to be had


def test_sweeps_skipped_in_the_first_ones_are_noted_once(tmp_path: Path) -> None:
    """The check's look at the first sweeps and the run's pass both met the duplicate and the late cloud:
    the run warned '2 sweep(s) skipped' twice (four, read as written). Negative control: the run's pass
    alone notes them once."""
    from tests.io.test_mcap_index import _multi_chunk_log

    log = tmp_path / "dup.mcap"
    _multi_chunk_log(log)
    with open_log(log) as lg:
        assert ground_check(lg, np.eye(4), Config()) is not None
        assert not [n for n in lg.health_notes() if "skipped" in n]
        assert len(list(lg.sweeps())) == 4
        assert [n for n in lg.health_notes() if "skipped" in n] == [
            "/ouster/points: 2 sweep(s) skipped: header stamp not after the previous sweep"]


def _warned(correction: tuple[float, float, float], user: tuple[float, float, float], *,
            apply: bool = True) -> tuple[str, dict[str, Any]]:
    """_add_ground_check's warning and record for a flagged reading `correction` (LiDAR axes, deg) made
    through /tf_static's mount with the user's `user` correction."""
    g = GroundMount(roll_deg=0.0, pitch_deg=correction[1], roll_sigma_deg=0.05, pitch_sigma_deg=0.05, points=5000,
                    residual_m=0.01, inlier_fraction=0.9, correction_rpy_deg=correction, verdict="misaligned",
                    reasons=[f"pitch {correction[1]:+.2f} +- 0.05 deg"])
    cfg = replace_paths(Config(), {"slam.sensor.mount_rpy_correction_deg": user, "slam.ground_mount.apply": apply})
    inputs = LogInputs(duration_s=60.0, base_to_sensor=np.eye(4), imu=None, sensor_to_imu=np.eye(4), gnss=None,
                       ground_truth=None, antenna=np.zeros(3), antenna_in_sensor=np.zeros(3), n_sweeps=300,
                       max_sweep_gap_s=0.1, ground_mount=g, mount_rpy_deg=applied_mount_rpy(cfg, g))
    result = RunResult(kind="slam", log_path="log.mcap", log_id="log", config_hash="0")
    _add_ground_check(result, inputs, cfg)
    assert len(result.warnings) == 1
    return result.warnings[0], result.extra["mount_check"]["ground"]


def test_the_ground_warning_under_a_set_correction_names_the_whole_value() -> None:
    """With slam.sensor.mount_rpy_correction_deg set the check reads through it, so a flagged reading is
    what is left on top of it: the value that takes it out is the two together ([0, 0.5, 0] set and
    0.5 more read: [0, 1, 0]), not the reading alone, and what is off is the corrected mount, not
    /tf_static. Negative control: nothing set, the reading is the value and /tf_static is named."""
    text, rec = _warned((0.0, 0.5, 0.0), (0.0, 0.5, 0.0))
    assert "slam.sensor.mount_rpy_correction_deg=[0.00, 1.00, 0.00]" in text
    assert "mount in /tf_static is off" not in text
    assert rec["applied"] is False
    text, rec = _warned((0.0, 0.5, 0.0), (0.0, 0.0, 0.0), apply=False)
    assert "slam.sensor.mount_rpy_correction_deg=[0.00, 0.50, 0.00]" in text
    assert "mount in /tf_static is off" in text
    assert rec["applied"] is False
    text, rec = _warned((0.0, 0.5, 0.0), (0.0, 0.0, 0.0))
    assert "applied [0.00, 0.50, 0.00] deg" in text
    assert rec["applied"] is True


def test_the_ground_warning_does_not_suggest_a_correction_the_config_refuses() -> None:
    """slam.sensor.mount_rpy_correction_deg takes +-10 deg: a reading beyond it (here 9 set + 2 read) is
    named as the /tf_static correction it needs, not as a setting the config would refuse."""
    text, _ = _warned((0.0, 2.0, 0.0), (0.0, 9.0, 0.0))
    assert "would take it out" not in text
    assert "mount_rpy_correction_deg=[0.00, 11" not in text
    assert "[0.00, 11.00, 0.00]" in text
    assert "+-10 deg" in text
