"""Where the open line's no-wheel error and end drift come from (issue 28, docs/simulation.md, "Seventh
session"): per seed, the SLAM without wheel odometry on the matrix's calibrated float (or RTK) log, and
against the log's ground truth

- the ENU -> map alignment's yaw error (the `gnss_track` events' yaw against the ideal one: the truth's
  heading put into the map by the first pose) and the end drift that error alone makes, 2 L sin(err / 2)
  over the drive's start-to-end distance L;
- the chain's yaw error at the end (the online heading against the truth's, both from their first pose);
- the fixes against the truth antenna (the sim's world frame is ENU at its default origin_lla; fixes
  are stamped gnss_latency_s = 0.12 s late): their RMS, the time a multipath jump is on (the 1 s running
  median of the error beyond 0.4 m), how many jumped fixes the track filter took and how many clean
  ones it gated out, the time it held a multipath offset;
- the track filter alone on the fixes (slam/gnss_track.track_filter, default slam.gps settings), its error
  after its own yaw + translation fit (the online APE's counterpart);
- the scan-to-map degeneracy events by number of degenerate directions.

Usage (from /tmp, logs made by wheel_gnss_matrix.py):

    python benchmarks/no_wheel_trace.py --seeds 0 1 2 3 4 5 [--gnss rtk] [--set slam.gps....=...]
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.ndimage import median_filter

from mrnc_eval.data import GnssSeries, Trajectory
from mrnc_eval.geodesy import lla_to_enu
from mrnc_eval.geometry import rotation
from mrnc_eval.geometry.point_fit import yaw_align
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_tum
from mrnc_eval.sim.config import FieldClockConfig, GnssSimConfig
from mrnc_eval.slam.config import GpsConfig
from mrnc_eval.slam.gnss_track import track_filter

JUMP_M = 0.4  # a 1 s running median of the fix error beyond this: a multipath jump is on (white noise 0.3 m / sqrt 5)
HEADER = ("| seed | online APE (m) | end drift (m) | alignment yaw error (deg) | 2 L sin(err/2) (m) | "
          "chain yaw error at end (deg) | fixes RMS (m) | time with a jump | jumped fixes taken | "
          "clean fixes gated out | time with an offset held | filter alone, own fit (m) | "
          "sweeps with 2 / 1 / 3 degenerate directions |")


def run_slam(log: Path, out: Path, sets: list[str]) -> Path:
    """The SLAM without wheel odometry on `log`; returns its run directory."""
    args = [sys.executable, "-m", "mrnc_eval.cli", "slam", str(log), "--json", "--out", str(out),
            "--set", "slam.wheel_odom.enabled=false", *[a for s in sets for a in ("--set", s)]]
    proc = subprocess.run(["nice", "-n", "5", *args], check=False, capture_output=True, text=True)
    return Path(json.loads(proc.stdout)["results"][0]["run_dir"])


def yaw_series(traj: Trajectory) -> np.ndarray:
    """Unwrapped yaw (rad) of every pose."""
    return np.unwrap(np.array([rotation.rpy(m)[2] for m in rotation.quat_to_matrix(traj.quat_xyzw)]))


def truth_antenna(gt: Trajectory, stamps: np.ndarray, lever: np.ndarray) -> np.ndarray:
    """The true antenna's x, y (world, m) at the fixes' measurement epochs (their stamps less the latency)."""
    t = stamps - FieldClockConfig().gnss_latency_s
    pos = np.column_stack([np.interp(t, gt.stamps, gt.positions[:, i]) for i in range(3)])
    k = np.clip(np.searchsorted(gt.stamps, t), 0, len(gt.stamps) - 1)
    rot = rotation.quat_to_matrix(gt.quat_xyzw[k])
    return np.asarray((pos + rot @ lever)[:, :2], np.float64)


def filter_alone(gnss: GnssSeries, cfg: GpsConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The track filter (default settings, not the run's --set) on every fix: per fix whether it was
    taken, the filter's position (ENU, m) and whether a multipath offset was held."""
    f = track_filter(cfg)
    taken, pos, held = [], [], []
    for t, z, cov in zip(gnss.stamps, gnss.enu[:, :2], gnss.covariance, strict=True):
        taken.append(f.update(float(t), z, float(np.sqrt(np.max(np.diag(cov)[:2])))))
        assert f.x is not None
        pos.append(f.x[:2].copy())
        held.append(bool(np.any(f.offset)))
    return np.array(taken), np.array(pos), np.array(held)


def jump_stats(err: np.ndarray, taken: np.ndarray, held: np.ndarray) -> dict[str, float]:
    """From the fixes' error (n, 2; m) against the truth and the filter's decisions: the fraction of
    fixes with a jump on, jumped fixes taken, clean fixes gated out, and the fraction with an offset held."""
    med = np.column_stack([median_filter(err[:, k], size=5, mode="nearest") for k in range(2)])
    jumped = np.linalg.norm(med, axis=1) > JUMP_M
    return {"rms": float(np.sqrt(np.mean(np.sum(err ** 2, axis=1)))), "jumped": float(jumped.mean()),
            "jumped_taken": int((jumped & taken).sum()), "jumped_n": int(jumped.sum()),
            "clean_out": int((~jumped & ~taken).sum()), "clean_n": int((~jumped).sum()), "held": float(held.mean())}


def own_fit_rms(xy: np.ndarray, ref: np.ndarray) -> float:
    """RMS (m) of xy against ref after the yaw + translation that fits them best."""
    r, t = yaw_align(np.c_[xy, np.zeros(len(xy))], np.c_[ref, np.zeros(len(ref))])
    return float(np.sqrt(np.mean(np.sum((xy @ r[:2, :2].T + t[:2] - ref) ** 2, axis=1))))


def alignment_row(res: dict, gt: Trajectory, est: Trajectory) -> dict[str, float]:
    """The alignment's yaw error (deg), the end drift it alone makes (m) and the chain's yaw error at the end (deg)."""
    yaws = [e["data"]["enu_to_map_yaw_deg"] for e in res["events"] if "enu_to_map_yaw_deg" in e.get("data", {})]
    ye, yg = yaw_series(est), np.interp(est.stamps, gt.stamps, yaw_series(gt))
    ideal = np.degrees(ye[0] - yg[0])  # world = ENU: its heading 0 is the map's heading ye0 - yg0
    err = float((yaws[-1] - ideal + 180.0) % 360.0 - 180.0) if yaws else float("nan")
    length = float(np.linalg.norm(gt.positions[-1, :2] - gt.positions[0, :2]))
    return {"align_err": err, "align_drift": abs(2.0 * length * np.sin(np.radians(err) / 2.0)),
            "chain_yaw_end": float(np.degrees((ye[-1] - ye[0]) - (yg[-1] - yg[0])))}


def trace(log: Path, run_dir: Path) -> str:
    """One table row for a log and its run."""
    res = json.loads((run_dir / "result.json").read_text())
    metrics = {m["name"]: m["value"] for m in res["metrics"]}
    gt, est = read_tum(log.with_suffix(".gt.tum")), read_tum(run_dir / "trajectory_online.tum")
    with open_log(log) as lg:
        gnss, lever = lg.gnss(), lg.transform("base_link", "gnss")[:3, 3]
    assert gnss is not None
    var = np.diagonal(gnss.covariance, axis1=1, axis2=2)[:, :2]
    usable = np.all(var <= GpsConfig().gps_cov_threshold_m2, axis=1) & np.all(np.isfinite(gnss.enu), axis=1)
    gnss = GnssSeries(stamps=gnss.stamps[usable], lla=gnss.lla[usable], enu=gnss.enu[usable],
                      covariance=gnss.covariance[usable], origin_lla=gnss.origin_lla)
    origin = lla_to_enu(np.array([GnssSimConfig().origin_lla]), gnss.origin_lla)[0, :2]
    truth = truth_antenna(gt, gnss.stamps, lever)
    taken, pos, held = filter_alone(gnss, GpsConfig())
    js = jump_stats(gnss.enu[:, :2] - origin - truth, taken, held)
    al = alignment_row(res, gt, est)
    deg = collections.Counter(e["data"].get("directions") for e in res["events"] if e["kind"] == "degeneracy")
    seed = log.stem.rsplit("_s", 1)[-1]
    return (f"| {seed} | {metrics['ape_online_rmse_m']:.3f} | {metrics['end_drift_online_m']:.1f} | "
            f"{al['align_err']:+.1f} | {al['align_drift']:.1f} | {al['chain_yaw_end']:+.1f} | {js['rms']:.2f} | "
            f"{js['jumped']:.0%} | {js['jumped_taken']}/{js['jumped_n']} | {js['clean_out']}/{js['clean_n']} | "
            f"{js['held']:.0%} | {own_fit_rms(pos, truth):.3f} | {deg.get(2, 0)} / {deg.get(1, 0)} / {deg.get(3, 0)} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", type=Path, default=Path("/tmp/wheels_logs"))
    p.add_argument("--gnss", choices=["float", "rtk"], default="float")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    p.add_argument("--set", dest="sets", action="append", default=[], help="a SLAM --set (repeatable)")
    a = p.parse_args()
    print(HEADER)
    print("|" + "---|" * HEADER.count(" | ") + "---|")
    for seed in a.seeds:
        log = a.logs / f"line_calibrated_{a.gnss}_s{seed}.mcap"
        with tempfile.TemporaryDirectory(prefix="no-wheel-trace-") as out:
            print(trace(log, run_slam(log, Path(out), a.sets)), flush=True)


if __name__ == "__main__":
    main()
