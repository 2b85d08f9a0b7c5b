"""The claims matrix of issue 28: scene x wheels x GNSS x seeds, online APE and end drift.

Scenes (field profile, OS0-32 x 512, 40 s, low-bandwidth packets): open line (open_field, 40 m
line at 1 m/s), open loop (open_field, the 20 x 12 m loop with 4 m corners at 0.7 m/s: 28.6 m, two
corners; at 1 m/s the outer side cannot follow the first corners and RAID's safety constraint
stopped the machine after ~13 m, so every loop cell before the tenth session was a 13 m drive and
a long stand), yard (yard circle), forest (5 m loop). A log whose simulated drive stopped
(`drive.safety_stops` in its errors record) is marked in the tables: it does not test what its
scene says.
Wheels: ideal (sim.wheels.model=exact: the plant's speeds, slip only), calibrated (the field
profile's default: scale 0.5 %, L/R 0.5 %, track 1.1x, 0.05 m/s noise), combined (2 %, 2 %, 1.6x,
0.05 m/s), lr2 (L/R 2 % only; for wheel_health), none (the calibrated log with
slam.wheel_odom.enabled=false). GNSS: float and rtk (sim.gnss.mode; every fix that type, float with
multipath jumps), none (--no-gps on the float log).

Each log is simulated once into --logs (default /tmp/wheels_logs) and reused; every SLAM result
is cached in <logs>/results-<label>.jsonl (delete it to re-run). Usage:

    python benchmarks/wheel_gnss_matrix.py generate --scenes line --wheels calibrated combined \
        --gnss float --seeds 3 4 5
    python benchmarks/wheel_gnss_matrix.py run --scenes line --wheels calibrated combined none --gnss float none \
        --seeds 3 4 5 --label report
    python benchmarks/wheel_gnss_matrix.py table --label report
    python benchmarks/wheel_gnss_matrix.py run --scenes line loop --wheels calibrated combined --gnss float \
        --seeds 0 1 2 --label midstart --start 5     # results-midstart-start5.jsonl: a log begun mid-drive

Seeds 0-2 are for tuning, 3-5 for the report (never tuned on).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

COMMON = ["--profile", "field", "--lidar", "os0-32", "--columns", "512", "--duration", "40",
          "--set", "sim.lidar.packet_profile=RNG15_RFL8_NIR8"]


def drive(speed_mps: float) -> list[str]:
    """Pure pursuit at a constant speed (the paper's speed cap off, the actuator's clamp raised)."""
    return ["--set", f"control.pure_pursuit.desired_speed_mps={speed_mps}", "--set",
            f"control.pure_pursuit.max_speed_mps={speed_mps}", "--set", "control.pure_pursuit.speed_cap=false",
            "--set", "control.actuator.u_max_rpm=4000"]


SCENES = {
    "line": ["--scene", "open_field", "--path", "line", "--set", "sim.path_size_m=40", *drive(1.0)],
    "loop": ["--scene", "open_field", "--path", "loop", "--set", "sim.path_size_m=20", *drive(0.7)],
    "yard": ["--scene", "yard", "--path", "circle"],
    "forest": ["--scene", "forest", "--path", "loop", "--set", "sim.path_size_m=5"],
}
WHEELS = {
    "ideal": ["--set", "sim.wheels.model=exact"],
    "calibrated": [],
    "combined": ["--set", "sim.wheels.scale_error=0.02", "--set", "sim.wheels.lr_mismatch=0.02",
                 "--set", "sim.wheels.track_factor=1.6"],
    "lr2": ["--set", "sim.wheels.scale_error=0", "--set", "sim.wheels.lr_mismatch=0.02",
            "--set", "sim.wheels.track_factor=1.0", "--set", "sim.wheels.speed_noise_mps=0"],
}
GNSS = {"float": ["--set", "sim.gnss.mode=float"], "rtk": ["--set", "sim.gnss.mode=rtk"]}
CLI = [sys.executable, "-m", "mrnc_eval.cli"]


def log_path(logs: Path, scene: str, wheels: str, gnss: str, seed: int) -> Path:
    """The log a cell runs on: wheels none uses the calibrated log, GNSS none the float log."""
    wheels = "calibrated" if wheels == "none" else wheels
    gnss = "float" if gnss == "none" else gnss
    return logs / f"{scene}_{wheels}_{gnss}_s{seed}.mcap"


def generate(logs: Path, scene: str, wheels: str, gnss: str, seed: int, extra: list[str]) -> Path:
    """Simulate the cell's log unless it exists (`extra`: more simulate --set arguments)."""
    out = log_path(logs, scene, wheels, gnss, seed)
    if not out.exists():
        args = [*CLI, "simulate", str(out), *COMMON, *SCENES[scene], *WHEELS[wheels], *GNSS[gnss], *extra,
                "--seed", str(seed)]
        subprocess.run(["nice", "-n", "5", *args], check=True, stdout=subprocess.DEVNULL)
    return out


def drive_stop_s(log: Path) -> float | None:
    """When the simulated drive was stopped by RAID's safety constraint (s since the log start), if it was."""
    errors = log.with_suffix(".errors.json")
    stops = json.loads(errors.read_text()).get("drive", {}).get("safety_stops", []) if errors.exists() else []
    return min((float(e["t_s"]) for e in stops), default=None)


def slam_args(wheels: str, gnss: str, method: str) -> list[str]:
    args = ["--method", method]
    if gnss == "none":
        args.append("--no-gps")
    if wheels == "none":
        args += ["--set", "slam.wheel_odom.enabled=false"]
    return args


def run_cell(log: Path, wheels: str, gnss: str, method: str, extra: list[str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="wheel-matrix-") as out:
        args = [*CLI, "slam", str(log), "--json", "--out", out, *slam_args(wheels, gnss, method), *extra]
        proc = subprocess.run(["nice", "-n", "5", *args], check=False, capture_output=True, text=True)
        try:  # a failed APE gate (gates.ape_rmse_max_m) exits non-zero after printing the summary
            data = json.loads(proc.stdout)  # {"schema_version", "verb", "results": [...]}; a bare list before
            row = (data["results"] if isinstance(data, dict) else data)[0]
            row = {**row, **row.get("stats", {})}  # the metrics moved under "stats"
        except (json.JSONDecodeError, IndexError, KeyError, TypeError):
            return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"}
        metrics = {}
        mfile = Path(row["run_dir"]) / "metrics.json"
        if mfile.exists():
            metrics = json.loads(mfile.read_text())
        return {"ape_online_m": row.get("ape_online_rmse_m"), "end_drift_online_m": row.get("end_drift_online_m"),
                "ape_smoothed_m": row.get("ape_rmse_m"), "wheel_health": metrics.get("wheel_health", {}),
                "mount_check": mount_record(metrics.get("mount_check", {})),
                "end_split": end_split(log.with_suffix(".gt.tum"), Path(row["run_dir"]) / "trajectory_online.tum")}


def mount_record(check: dict) -> dict:
    """The motion check of the LiDAR mount (the final pass's and, when slam.mount_check.apply ran the log
    again, the first pass's): verdict, pitch and yaw with their sigmas (deg)."""
    keys = ("verdict", "pitch_deg", "pitch_sigma_deg", "yaw_deg", "yaw_sigma_deg")
    out = {k: check.get(k) for k in keys}
    if "first_pass" in check:
        out["first_pass"] = {k: check["first_pass"].get(k) for k in keys}
    return out


def end_split(gt_file: Path, online_file: Path) -> dict[str, float] | None:
    """The online end drift split as end_drift_online_m measures it (the first poses made to
    coincide, evo's origin alignment): along-track, cross-track (left +), vertical (m) and yaw (deg)
    of the last pose, and the first pose's roll and pitch error (deg, estimate minus truth; the
    alignment tilts the whole trajectory by it: 0.4 deg of pitch is 0.28 m of z at 40 m)."""
    if not gt_file.exists() or not online_file.exists():
        return None
    import numpy as np

    from mrnc_eval.evaluation.ape import ape
    from mrnc_eval.geometry import rotation
    from mrnc_eval.io.trajectory_files import read_tum

    gt, est = read_tum(gt_file), read_tum(online_file)
    d = ape(gt, est, align="origin", max_diff=0.05).decompose()
    i = int(abs(gt.stamps - est.stamps[0]).argmin())
    tilt = [rotation.rpy(rotation.quat_to_matrix(q[None])[0]) for q in (est.quat_xyzw[0], gt.quat_xyzw[i])]
    roll, pitch = np.degrees(tilt[0][:2] - tilt[1][:2])
    return {"along_m": float(d.along_m[-1]), "cross_m": float(d.cross_m[-1]), "z_m": float(d.vertical_m[-1]),
            "yaw_deg": float(d.yaw_deg[-1]), "first_roll_deg": float(roll), "first_pitch_deg": float(pitch),
            **height_checks(gt, est)}


def height_checks(gt, est) -> dict[str, float]:
    """Where the end z comes from (docs/simulation.md, "holding the line's z"): `map_climb_deg`, the
    estimate's climb in its map minus the truth's (start to end over the horizontal distance; the
    map's tilt from the IMU's start, which the origin alignment takes out with the first pose's
    tilt: first pitch error + map climb = the base_link mount's pitch error), and `z_height_held_m`,
    the end z had every height been the truth's (what a perfect GNSS height hold would give)."""
    import dataclasses

    import numpy as np

    from mrnc_eval.evaluation.ape import ape

    idx = np.abs(gt.stamps[None, :] - est.stamps[:, None]).argmin(axis=1)
    dz_est, dz_gt = est.positions[-1, 2] - est.positions[0, 2], gt.positions[idx[-1], 2] - gt.positions[idx[0], 2]
    run = float(np.linalg.norm(est.positions[-1, :2] - est.positions[0, :2]))
    held = est.positions.copy()
    held[:, 2] = held[0, 2] + gt.positions[idx, 2] - gt.positions[idx[0], 2]
    z = ape(gt, dataclasses.replace(est, positions=held), align="origin", max_diff=0.05).decompose().vertical_m[-1]
    return {"map_climb_deg": float(np.degrees(np.arctan2(dz_est - dz_gt, max(run, 1e-9)))), "z_height_held_m": float(z)}


def cells(a: argparse.Namespace):
    for scene in a.scenes:
        for wheels in a.wheels:
            for gnss in a.gnss:
                for seed in a.seeds:
                    yield scene, wheels, gnss, seed


def results_file(logs: Path, label: str) -> Path:
    return logs / f"results-{label}.jsonl"


def load(logs: Path, label: str) -> dict[tuple, dict]:
    f = results_file(logs, label)
    out = {}
    if f.exists():
        for line in f.read_text().splitlines():
            r = json.loads(line)
            out[(r["scene"], r["wheels"], r["gnss"], r["seed"], r["method"])] = r
    return out


def table(results: dict[tuple, dict]) -> str:
    """Markdown: per cell the median and worst online APE and end drift over the seeds."""
    groups: dict[tuple, list[dict]] = {}
    for (scene, wheels, gnss, _seed, method), r in sorted(results.items()):
        groups.setdefault((scene, wheels, gnss, method), []).append(r)
    lines = ["| scene | wheels | GNSS | method | seeds | online APE median / worst (m) | end drift median / worst (m) "
             "| wheel_health verdicts | track factor (est.) |", "|---|---|---|---|---|---|---|---|---|"]
    for (scene, wheels, gnss, method), rs in groups.items():
        ok = [r for r in rs if r.get("ape_online_m") is not None]
        seeds = ",".join(str(r["seed"]) for r in rs) + _stopped(rs)
        if not ok:
            lines.append(f"| {scene} | {wheels} | {gnss} | {method} | {seeds} | failed | | | |")
            continue
        ape = [r["ape_online_m"] for r in ok]
        drift = [r["end_drift_online_m"] for r in ok]
        verdicts = ",".join(str(r.get("wheel_health", {}).get("verdict", "-")) for r in ok)
        tf = ",".join(f"{r['wheel_health']['track_factor']:.2f}" for r in ok
                      if r.get("wheel_health", {}).get("track_factor") is not None)
        lines.append(f"| {scene} | {wheels} | {gnss} | {method} | {seeds} | {statistics.median(ape):.3f} / "
                     f"{max(ape):.3f} | {statistics.median(drift):.2f} / {max(drift):.2f} | {verdicts} | {tf} |")
    return "\n".join(lines)


def _stopped(rs: list[dict]) -> str:
    """The seeds column's mark for drives RAID's safety constraint stopped (s since the log start)."""
    stops = [r["drive_stop_s"] for r in rs if r.get("drive_stop_s") is not None]
    return f" (drive stopped at {min(stops):.1f}-{max(stops):.1f} s on {len(stops)})" if stops else ""


def split_table(results: dict[tuple, dict]) -> str:
    """Markdown: per cell and seed the online APE, the end drift and its split (`end_split`)."""
    lines = ["| scene | wheels | GNSS | seed | online APE (m) | end drift (m) | along / cross / z (m) | yaw (deg) "
             "| first roll / pitch error (deg) | map climb (deg) | z, heights held (m) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (scene, wheels, gnss, seed, _method), r in sorted(results.items()):
        sp = r.get("end_split")
        if r.get("ape_online_m") is None or not sp:
            continue
        lines.append(f"| {scene} | {wheels} | {gnss} | {seed} | {r['ape_online_m']:.3f} "
                     f"| {r['end_drift_online_m']:.2f} | {sp['along_m']:+.2f} / {sp['cross_m']:+.2f} "
                     f"/ {sp['z_m']:+.2f} | {sp['yaw_deg']:+.2f} "
                     f"| {sp['first_roll_deg']:+.2f} / {sp['first_pitch_deg']:+.2f} "
                     f"| {_signed(sp.get('map_climb_deg'))} | {_signed(sp.get('z_height_held_m'))} |")
    return "\n".join(lines)


def _signed(x: float | None) -> str:
    """A split column (results from before the column was added: -)."""
    return "-" if x is None else f"{x:+.2f}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("command", choices=["generate", "run", "table"])
    p.add_argument("--logs", type=Path, default=Path(os.environ.get("MRNC_WHEEL_LOGS", "/tmp/wheels_logs")))
    p.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    p.add_argument("--wheels", nargs="+", default=["ideal", "calibrated", "combined", "none"],
                   choices=[*WHEELS, "none"])
    p.add_argument("--gnss", nargs="+", default=["none", "float", "rtk"], choices=["none", *GNSS])
    p.add_argument("--seeds", nargs="+", type=int, default=[3, 4, 5])
    p.add_argument("--method", default="lio", choices=["lio", "kiss-icp"])
    p.add_argument("--label", default="report", help="results file name part (a code version or experiment)")
    p.add_argument("--split", action="store_true", help="table: per seed, the online end drift split into "
                   "along, cross, z and yaw, and the first pose's tilt error")
    p.add_argument("--start", type=float, default=None, help="slam --start S: the log cut S s after its start "
                   "(sweeps, IMU, wheels, GNSS), as a log recorded mid-drive; the label gets -start<S>")
    p.add_argument("--set", dest="sets", action="append", default=[], help="extra slam --set KEY=VALUE")
    p.add_argument("--sim-set", dest="sim_sets", action="append", default=[], help="extra simulate --set "
                   "KEY=VALUE for logs not yet made (log names do not carry it: give such logs their own --logs)")
    a = p.parse_args()
    a.logs.mkdir(parents=True, exist_ok=True)
    if a.start is not None:  # its own results file: never mixed with the standing-start cells
        a.label = f"{a.label}-start{a.start:g}"
    if a.command == "table":
        print(split_table(load(a.logs, a.label)) if a.split else table(load(a.logs, a.label)))
        return
    done = load(a.logs, a.label)
    extra = [x for s in a.sets for x in ("--set", s)] + ([] if a.start is None else ["--start", f"{a.start:g}"])
    for scene, wheels, gnss, seed in cells(a):
        gen_wheels = "calibrated" if wheels == "none" else wheels
        log = generate(a.logs, scene, gen_wheels, "float" if gnss == "none" else gnss, seed,
                       [x for s in a.sim_sets for x in ("--set", s)])
        if a.command == "generate" or (scene, wheels, gnss, seed, a.method) in done:
            continue
        r = {"scene": scene, "wheels": wheels, "gnss": gnss, "seed": seed, "method": a.method,
             "drive_stop_s": drive_stop_s(log), **run_cell(log, wheels, gnss, a.method, extra)}
        with results_file(a.logs, a.label).open("a") as f:
            f.write(json.dumps(r) + "\n")
        print(json.dumps({k: v for k, v in r.items() if k != "wheel_health"}), flush=True)
    if a.command == "run":
        print(table(load(a.logs, a.label)))


if __name__ == "__main__":
    main()
