"""The 18 reproductions of issue 15, each run the way a hostile user would: through the CLI
(`mrnc_eval.cli.main` in-process, or a subprocess where the user matters), on small simulated
logs with one defect written in.

Each case returns a `Outcome` (exit code, expected code, whether the harm was avoided);
tests/test_reliability_cli.py asserts them, and

    PYTHONPATH=. python -m tests.reliability_cases

prints the table of cases with the exit codes they produce (the closing note's table).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

REPO = Path(__file__).resolve().parents[1]


@dataclass
class Outcome:
    case: str
    command: str
    code: int
    expected: int
    harm_avoided: bool  # the data, the number or the line the issue was about is right
    detail: str = ""
    parts: list[tuple[str, int, bool]] = field(default_factory=list)  # (sub-case, exit, right) for item 18

    @property
    def ok(self) -> bool:
        return self.code == self.expected and self.harm_avoided


@dataclass
class Run:
    code: int
    out: str
    err: str


@dataclass
class Workspace:
    root: Path  # a fresh folder per case
    sim_log: Path  # a 2-s simulated MCAP (os0-32, 512 columns) with <name>.gt.tum beside it

    def path(self, *parts: str) -> Path:
        p = self.root.joinpath(*parts)
        p.parent.mkdir(parents=True, exist_ok=True)
        return p


# ------------------------------------------------------------------ helpers


def cli(*argv: object) -> Run:
    """`mrnc-eval ARGV` in this process; stdout and stderr captured."""
    from mrnc_eval.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return Run(code, out.getvalue(), err.getvalue())


def one_line(run: Run) -> bool:
    """The error is one line on stderr, with no traceback."""
    lines = [ln for ln in run.err.splitlines() if ln.strip() and not ln.startswith(("WARNING", "INFO"))]
    return len(lines) == 1 and "Traceback" not in run.err


def rewrite_log(src: Path, dst: Path, edits: dict[str, Callable[[Any, int], Any]]) -> Path:
    """Copy a log message by message, passing the messages of the edited topics (with their
    index) through `edits`: a log with one defect written in. The ground truth TUM follows."""
    from mrnc_eval.io import open_log
    from mrnc_eval.io.ground_truth import gt_tum_path
    from mrnc_eval.io.writers import LogWriter

    counts: dict[str, int] = {}
    with open_log(src) as lg, LogWriter(dst, "mcap") as w:
        for topic, t_rec, raw in lg.source.iterate(list(lg.source.channels)):
            msgtype = lg.source.channels[topic].msgtype
            if topic in edits:
                k = counts.get(topic, 0)
                counts[topic] = k + 1
                raw = w._serialize(edits[topic](lg.source.decode(raw, topic), k), msgtype)
            w._writer.write(w._conn(topic, msgtype, latched=topic == "/tf_static"), t_rec, bytes(raw))
    if gt_tum_path(src).exists():
        shutil.copy(gt_tum_path(src), gt_tum_path(dst))
    return dst


def make_sim_log(folder: Path) -> Path:
    from mrnc_eval.config import Config
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    cfg = Config()
    cfg = replace(cfg, sim=replace(cfg.sim, lidar=replace(cfg.sim.lidar, record_every=2)))
    return simulate_log(folder / "s.mcap", cfg, SimRequest(duration_s=2.0, lidar="os0-32", columns=512, seed=1))


@contextlib.contextmanager
def cwd(path: Path) -> Iterator[None]:
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


@contextlib.contextmanager
def umask(mask: int) -> Iterator[None]:
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def run_folders(out: Path) -> list[Path]:
    """The result folders under an output root (not the OUT/latest link, which repeats one)."""
    return sorted(p for p in out.iterdir() if p.is_dir() and not p.is_symlink()) if out.exists() else []


def tree_snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _cmd(*argv: object) -> str:
    return "mrnc-eval " + " ".join(str(a) for a in argv)


# ------------------------------------------------------------------ 1, 2, 10, 11: data loss


def case_01a_simulate_into_user_folder(ws: Workspace) -> Outcome:
    d = ws.path("d")
    d.mkdir()
    (d / "f").write_text("x\n")
    argv = ("simulate", d, "--duration", 2, "--lidar", "os0-32", "--columns", 512)
    r = cli(*argv)
    return Outcome("1a", _cmd("simulate d --duration 2 --lidar os0-32 --columns 512"), r.code, 4,
                   (d / "f").read_text() == "x\n" and one_line(r), r.err.strip())


def case_01b_simulate_dot(ws: Workspace) -> Outcome:
    (ws.root / "keep.txt").write_text("mine\n")
    with cwd(ws.root):
        r = cli("simulate", ".", "--duration", 2, "--lidar", "os0-32", "--columns", 512)
        r_force = cli("simulate", ".", "--force", "--duration", 2, "--lidar", "os0-32", "--columns", 512)
    kept = (ws.root / "keep.txt").read_text() == "mine\n"
    return Outcome("1b", _cmd("simulate . (and --force)"), max(r.code, r_force.code), 2,
                   kept and r.code == r_force.code == 2 and one_line(r), r.err.strip())


def case_01c_simulate_over_recording(ws: Workspace) -> Outcome:
    rec = ws.path("existing.bag")
    rec.write_bytes(b"#ROSBAG V2.0\nprecious recording")
    r = cli("simulate", rec, "--format", "bag", "--duration", 2, "--lidar", "os0-32", "--columns", 512)
    r_force = cli("simulate", rec, "--format", "bag", "--force", "--duration", 2, "--lidar", "os0-32",
                  "--columns", 512)
    kept = rec.read_bytes() == b"#ROSBAG V2.0\nprecious recording"
    return Outcome("1c", _cmd("simulate existing.bag [--force]"), max(r.code, r_force.code), 4,
                   kept and r.code == r_force.code == 4 and one_line(r_force), r_force.err.strip())


def case_02a_slam_same_log_name(ws: Workspace) -> Outcome:
    a, b = ws.path("a", "run.mcap"), ws.path("b", "run.mcap")
    shutil.copy(ws.sim_log, a)
    rewrite_log(ws.sim_log, b, {})  # same content, another file
    out = ws.path("X")
    r = cli("slam", a, b, "--out", out, "--no-loop")
    runs = sorted(p for p in out.iterdir() if p.is_dir() and not p.is_symlink())  # OUT/latest repeats one
    logs = {json.loads((p / "result.json").read_text())["log_path"] for p in runs}
    table_rows = [ln for ln in r.out.splitlines() if ln.startswith("| ") and "run" in ln]
    return Outcome("2a", _cmd("slam a/run.mcap b/run.mcap --out X"), r.code, 0,
                   len(runs) == 2 and logs == {str(a), str(b)} and len(set(table_rows)) == 2,
                   f"{len(runs)} run folders, Table I rows {[row.split('|')[1].strip() for row in table_rows]}")


def case_02b_control_same_second(ws: Workspace) -> Outcome:
    out = ws.path("X")
    r1 = cli("control", "--mode", "simulate", "--controllers", "pid", "--out", out, "--set", "control.pid.kp=4000")
    r2 = cli("control", "--mode", "simulate", "--controllers", "pid", "--out", out, "--set", "control.pid.kp=5000")
    runs = sorted(p for p in out.iterdir() if p.is_dir() and not p.is_symlink())  # OUT/latest repeats one
    kps = {json.loads((p / "result.json").read_text())["config_hash"] for p in runs}
    return Outcome("2b", _cmd("control --mode simulate --set control.pid.kp=4000 / =5000 (same second)"),
                   max(r1.code, r2.code), 0, len(runs) == 2 and len(kps) == 2, f"{len(runs)} run folders")


def case_10a_out_is_a_file(ws: Workspace) -> Outcome:
    f = ws.path("taken")
    f.write_text("user file\n")
    runs = [cli("slam", ws.sim_log, "--out", f), cli("control", "--mode", "simulate", "--controllers", "pid",
                                                        "--out", f),
            cli("nightly", ws.sim_log.parent, "--out", f, "--jobs", 1),
            cli("ape", f"{ws.sim_log}:/ground_truth", f"{ws.sim_log}:/wheel_odom", "--table", f / "t.md"),
            cli("ape", f"{ws.sim_log}:/ground_truth", f"{ws.sim_log}:/wheel_odom", "--plot", f / "p.svg")]
    codes = [r.code for r in runs]
    return Outcome("10a", _cmd("slam|control|nightly --out FILE; ape --table FILE/t.md, --plot FILE/p.svg"),
                   max(codes), 4, codes == [4] * 5 and all(one_line(r) for r in runs) and
                   f.read_text() == "user file\n", "; ".join(r.err.strip() for r in runs[:1]))


@contextlib.contextmanager
def read_only(folder: Path) -> Iterator[None]:
    """A folder nobody may write into, root included (root ignores modes: the immutable flag)."""
    if os.geteuid() != 0:
        os.chmod(folder, 0o555)
        try:
            yield
        finally:
            os.chmod(folder, 0o755)
        return
    if subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode != 0:
        denied = PermissionError(errno.EACCES, "Permission denied", str(folder))
        with mock.patch("tempfile.NamedTemporaryFile", side_effect=denied):  # no chattr here: the same error
            yield
        return
    try:
        yield
    finally:
        subprocess.run(["chattr", "-i", str(folder)], check=True)


def case_10b_read_only_out(ws: Workspace) -> Outcome:
    out = ws.path("ro")
    out.mkdir()
    with read_only(out):
        r = cli("slam", ws.sim_log, "--out", out)
    return Outcome("10b", _cmd("slam LOG --out READ_ONLY_DIR"), r.code, 4,
                   one_line(r) and "cannot write here" in r.err and "APE" not in r.out, r.err.strip())


def case_10c_disk_full(ws: Workspace) -> Outcome:
    out = ws.path("full")
    usage = shutil.disk_usage(ws.root)
    with mock.patch("shutil.disk_usage", return_value=usage._replace(free=10_000_000)):
        before = cli("slam", ws.sim_log, "--out", out)  # refused before the run
    with mock.patch("numpy.savez_compressed", side_effect=OSError(errno.ENOSPC, "No space left on device")):
        during = cli("control", "--mode", "simulate", "--controllers", "pid", "--out", out)  # fails while writing
    leftovers = [p.name for p in out.iterdir()] if out.exists() else []
    return Outcome("10c", _cmd("slam/control --out FULL_DISK"), max(before.code, during.code), 4,
                   before.code == during.code == 4 and one_line(before) and one_line(during) and not leftovers,
                   f"{before.err.strip()} | {during.err.strip()}")


def _weasyprint_disk_full() -> Any:
    class FullDiskHtml:
        def __init__(self, **_: Any) -> None:
            pass

        def write_pdf(self, target: Any) -> None:
            raise OSError(errno.ENOSPC, "No space left on device", str(target))

    return mock.patch("weasyprint.HTML", FullDiskHtml)


def case_11_nightly_disk_full(ws: Workspace) -> Outcome:
    from tests.reports.conftest import write_imu_log

    first_logs, logs, out = ws.path("logs1"), ws.path("logs2"), ws.path("reports")
    first_logs.mkdir()
    write_imu_log(first_logs / "imu.mcap", 30)  # an earlier night (its log fails fast: no LiDAR)
    logs.mkdir()
    shutil.copy(ws.sim_log, logs / "s.mcap")
    shutil.copy(ws.sim_log.with_name("s.gt.tum"), logs / "s.gt.tum")
    first = cli("nightly", first_logs, "--out", out, "--jobs", 1, "--date", "2026-01-01", "--no-pdf")
    earlier = tree_snapshot(out / "2026-01-01")
    with _weasyprint_disk_full():
        second = cli("nightly", logs, "--out", out, "--jobs", 1, "--date", "2026-01-02", "--pdf")
    with contextlib.closing(sqlite3.connect(out / "history.sqlite")) as db:
        status = dict(db.execute("SELECT night, status FROM runs").fetchall())
        error = db.execute("SELECT error FROM runs WHERE night = '2026-01-02'").fetchone()[0]
    placeholder = list((out / "2026-01-02").rglob("report.pdf"))
    harm = (status == {"2026-01-01": "failed", "2026-01-02": "failed"} and "no space" in error.lower()
            and not placeholder and tree_snapshot(out / "2026-01-01") == earlier
            and (out / "2026-01-02" / "index.html").exists())
    return Outcome("11", _cmd("nightly LOGS --out R (disk full at the PDF step)"), second.code, 3,
                   first.code == 3 and harm, f"log status {status.get('2026-01-02')}: {error[:90]}")


def case_11b_history_rollback(ws: Workspace) -> Outcome:
    from mrnc_eval.errors import OutputError
    from mrnc_eval.history import History, LogRecord

    history = History(ws.path("h", "history.sqlite"))
    real = history._connect

    class FullDisk:
        """A connection whose inserts fail as on a full disk and whose ROLLBACK then fails too."""

        def __init__(self) -> None:
            self.db = real()

        def execute(self, sql: str, *args: Any) -> Any:
            if sql.startswith("INSERT"):
                raise sqlite3.OperationalError("database or disk is full")
            if sql == "ROLLBACK":
                raise sqlite3.OperationalError("cannot rollback - no transaction is active")
            return self.db.execute(sql, *args)

        def executemany(self, sql: str, *args: Any) -> Any:
            return self.db.executemany(sql, *args)

        def close(self) -> None:
            self.db.close()

    rec = LogRecord("2026-01-01", "a", "r", "a.mcap", "v", "h", "ok", "", "t", (("m", 1.0, ""),))
    with mock.patch.object(history, "_connect", FullDisk):
        try:
            history.record(rec)
            message = ""
        except OutputError as err:
            message = str(err)
    return Outcome("11b", "history write on a full disk (library call)", 4 if message else 0, 4,
                   "disk is full" in message and "rollback" not in message, message)


# ------------------------------------------------------------------ 3-7: bad numbers


def _nan_wheels(msg: Any, _: int) -> Any:
    msg.velocity = np.full(len(msg.velocity), np.nan)
    return msg


def case_03_nan_wheel_speeds(ws: Workspace) -> Outcome:
    log = rewrite_log(ws.sim_log, ws.path("nan_wheels.mcap"), {"/wheel_speeds": _nan_wheels})
    r = cli("control", log, "--mode", "replay", "--out", ws.root / "R")
    out = ws.root / "R"
    nothing_written = not out.exists() or not any(out.iterdir())
    return Outcome("3", _cmd("control NAN_WHEELS_LOG --mode replay"), r.code, 4,
                   one_line(r) and "/wheel_speeds" in r.err and nothing_written, r.err.strip())


def case_04_lidar_frame_mismatch(ws: Workspace) -> Outcome:
    r = cli("slam", ws.sim_log, "--out", ws.path("R"), "--set", "slam.sensor.lidar_frame=velodyne")
    return Outcome("4", _cmd("slam LOG --set slam.sensor.lidar_frame=velodyne (not the clouds' frame)"), r.code, 4,
                   one_line(r) and "lidar_frame" in r.err, r.err.strip())


def _lat(value: float) -> Callable[[Any, int], Any]:
    def edit(msg: Any, _: int) -> Any:
        msg.latitude = value
        return msg

    return edit


def case_05_impossible_latitude(ws: Workspace) -> Outcome:
    codes, errs = [], []
    for lat in (1000.0, 91.5):
        log = rewrite_log(ws.sim_log, ws.path(f"lat{lat:g}.mcap"), {"/gnss/fix": _lat(lat)})
        r = cli("slam", log, "--out", ws.path("R"))
        codes.append(r.code)
        errs.append(r.err.strip())
    return Outcome("5", _cmd("slam LAT_1000_LOG; slam LAT_91.5_LOG"), max(codes), 4,
                   codes == [4, 4] and all("latitude" in e for e in errs), errs[0])


def _zero_quat(msg: Any, _: int) -> Any:
    o = msg.pose.pose.orientation
    o.x = o.y = o.z = o.w = 0.0
    return msg


def case_06_zero_quaternions(ws: Workspace) -> Outcome:
    log = rewrite_log(ws.sim_log, ws.path("zero_q.mcap"), {"/ground_truth": _zero_quat})
    r = cli("ape", f"{log}:/ground_truth", f"{log}:/wheel_odom", "--relation", "angle_deg")
    return Outcome("6", _cmd("ape LOG:/ground_truth LOG:/wheel_odom --relation angle_deg (all-zero quaternions)"),
                   r.code, 4, one_line(r) and "quaternion" in r.err and r.out == "", r.err.strip())


def case_07_bad_parameters(ws: Workspace) -> Outcome:
    runs = [cli("control", "--mode", "simulate", "--controllers", "raid", "--out", ws.path("R"),
                "--set", "control.raid.beta=nan"),
            cli("control", ws.sim_log, "--mode", "replay", "--out", ws.path("R"), "--set", "robot.wheel_radius_m=-1")]
    return Outcome("7", _cmd("control --set control.raid.beta=nan; control LOG --set robot.wheel_radius_m=-1"),
                   max(r.code for r in runs), 2,
                   [r.code for r in runs] == [2, 2] and all(one_line(r) for r in runs) and not ws.path("R").exists(),
                   " | ".join(r.err.strip() for r in runs))


# ------------------------------------------------------------------ 8, 9, 12, 13: crashes and exit codes


def _no_fix(msg: Any, _: int) -> Any:
    msg.status.status = -1
    return msg


def case_08_no_gnss_fix(ws: Workspace) -> Outcome:
    log = rewrite_log(ws.sim_log, ws.path("nofix.mcap"), {"/gnss/fix": _no_fix})
    out = ws.path("R")
    r = cli("slam", log, "--out", out, "--no-gps", "--no-loop")
    warnings = [w for p in run_folders(out) for w in json.loads((p / "result.json").read_text())["warnings"]]
    return Outcome("8", _cmd("slam NO_FIX_LOG --no-gps"), r.code, 0,
                   any("no valid GNSS fix" in w for w in warnings), "; ".join(warnings)[:120])


def _nan_orientation(msg: Any, _: int) -> Any:
    msg.orientation.x = msg.orientation.y = msg.orientation.z = msg.orientation.w = np.nan
    msg.orientation_covariance = np.r_[0.01, np.zeros(8)]  # REP-145: orientation present
    return msg


def _nan_static_rotation(msg: Any, _: int) -> Any:
    msg.transforms[0].transform.rotation.w = np.nan
    return msg


def case_09_nan_rotations(ws: Workspace) -> Outcome:
    """NaN IMU orientations: the IMU is used without orientation (a note, exit 0); a NaN rotation
    in /tf_static: one line, exit 4. Neither is scipy's traceback with exit 1."""
    imu_log = rewrite_log(ws.sim_log, ws.path("nan_imu_q.mcap"), {"/ouster/imu": _nan_orientation})
    tf_log = rewrite_log(ws.sim_log, ws.path("nan_tf.mcap"), {"/tf_static": _nan_static_rotation})
    out = ws.path("R")
    runs = [cli("slam", imu_log, "--out", out, "--no-loop"), cli("slam", tf_log, "--out", out)]
    warnings = [w for p in run_folders(out) for w in json.loads((p / "result.json").read_text())["warnings"]]
    noted = any("orientation ignored" in w for w in warnings)
    return Outcome("9", _cmd("slam NAN_IMU_ORIENTATION_LOG; slam NAN_TF_STATIC_LOG"), max(r.code for r in runs), 4,
                   [r.code for r in runs] == [0, 4] and noted and one_line(runs[1]) and "quaternion" in runs[1].err,
                   f"IMU: exit {runs[0].code}, noted {noted}; tf: {runs[1].err.strip()[:120]}")


def case_12_bad_config_values(ws: Workspace) -> Outcome:
    latin1 = ws.path("latin1.yaml")
    latin1.write_bytes("robot:\n  name: Mäschine\n".encode("latin-1"))
    runs = [cli("config", "--set", "slam.imu.gravity=nan"), cli("config", "--set", "slam.imu.acc_noise=-1"),
            cli("config", "--config", latin1)]
    return Outcome("12", _cmd("config --set slam.imu.gravity=nan | --set slam.imu.acc_noise=-1 | --config LATIN1"),
                   max(r.code for r in runs), 2,
                   [r.code for r in runs] == [2, 2, 2] and all(one_line(r) for r in runs),
                   " | ".join(r.err.strip() for r in runs))


def bomb_text(depth: int) -> str:
    """A small YAML whose robot.name expands to 9**depth strings."""
    anchors = "[" + ", ".join(["lol"] * 9) + "]"
    text = f"robot:\n  name:\n    - &a0 {anchors}\n"
    for k in range(1, depth + 1):
        text += f"    - &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]\n"
    return text


def bomb_flow(depth: int) -> str:
    """The same bomb as one flow-style YAML value (for --set)."""
    items = ["&a0 [" + ", ".join(["lol"] * 9) + "]"]
    items += [f"&a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, depth + 1)]
    return "[" + ", ".join(items) + "]"


def case_13_alias_bomb(ws: Workspace) -> Outcome:
    import time

    cfg = ws.path("bomb.yaml")
    cfg.write_text(bomb_text(9))
    t0 = time.perf_counter()
    r_file = cli("config", "--config", cfg)
    r_set = cli("config", "--set", "robot.name=" + bomb_flow(9))
    elapsed = time.perf_counter() - t0
    size = cfg.stat().st_size
    return Outcome("13", _cmd(f"config --config BOMB.yaml ({size} bytes, depth 9); --set robot.name=BOMB"),
                   max(r_file.code, r_set.code), 2,
                   r_file.code == r_set.code == 2 and elapsed < 5.0 and len(r_file.err) < 400 and len(r_set.err) < 400,
                   f"{elapsed:.2f} s; {r_file.err.strip()}")


# ------------------------------------------------------------------ 14-18: hygiene


def case_14_umask_permissions(ws: Workspace) -> Outcome:
    out = ws.path("R")
    with umask(0o022):
        r = cli("control", "--mode", "simulate", "--controllers", "pid", "--out", out)
        run = run_folders(out)[0]
        rep = cli("report", run)
    modes = {str(p.relative_to(out)): p.stat().st_mode & 0o777 for p in out.rglob("*")}
    wrong = {k: oct(m) for k, m in modes.items() if m != (0o755 if (out / k).is_dir() else 0o644)}
    return Outcome("14", _cmd("control --mode simulate; report RUN (umask 022)"), max(r.code, rep.code), 0,
                   not wrong and len(modes) > 3, f"{len(modes)} paths, wrong modes: {wrong}")


FORGED_TOPIC = "/gnss\nERROR forged line \x1b[31mred"


def case_15_forged_topic(ws: Workspace) -> Outcome:
    from mrnc_eval.io.writers import LogWriter

    log = ws.path("forged.mcap")
    with LogWriter(log, "mcap") as w:
        n = 20
        w.write_navsatfix(FORGED_TOPIC, 1.0 + np.arange(n) * 0.2, np.tile([61.0, 23.0, 100.0], (n, 1)),
                          np.tile(np.eye(3).ravel(), (n, 1)), np.zeros(n, int))
    r = cli("info", log)
    return Outcome("15", _cmd("info LOG (topic '/gnss\\nERROR forged line \\x1b[31m...')"), r.code, 0,
                   "\x1b" not in r.out and not any(ln.startswith("ERROR forged") for ln in r.out.splitlines())
                   and "\\x1b" in r.out, "escaped: " + str("\\nERROR forged" in r.out))


def case_16_non_ascii_ids(ws: Workspace) -> Outcome:
    from tests.reports.conftest import write_imu_log

    logs, out = ws.path("logs"), ws.path("reports")
    logs.mkdir()
    write_imu_log(logs / "Übung.mcap", 30)
    write_imu_log(logs / "Ölfeld.mcap", 30)
    first = cli("nightly", logs, "--out", out, "--jobs", 1, "--date", "2026-01-01", "--no-pdf")
    write_imu_log(logs / "Ähre.mcap", 30)  # sorts before the others
    second = cli("nightly", logs, "--out", out, "--jobs", 1, "--date", "2026-01-02", "--no-pdf")
    with contextlib.closing(sqlite3.connect(out / "history.sqlite")) as db:
        rows = db.execute("SELECT night, log_id, log_path FROM runs").fetchall()
    ids = {(night, Path(path).name): log_id for night, log_id, path in rows}
    stable = all(ids[("2026-01-01", n)] == ids[("2026-01-02", n)] for n in ("Übung.mcap", "Ölfeld.mcap"))
    distinct = len({i for (night, _), i in ids.items() if night == "2026-01-02"}) == 3
    return Outcome("16", _cmd("nightly LOGS (Übung, Ölfeld; then Ähre added)"), second.code, 3,
                   first.code == 3 and stable and distinct and all(i.isascii() for i in ids.values()),
                   ", ".join(sorted({i for i in ids.values()})))


def case_17_impossible_date(ws: Workspace) -> Outcome:
    out = ws.path("R")
    r = cli("nightly", ws.sim_log.parent, "--out", out, "--date", "2026-13-45")
    return Outcome("17", _cmd("nightly DIR --out R --date 2026-13-45"), r.code, 2,
                   one_line(r) and not out.exists(), r.err.strip())


def _nan_imu_sample(msg: Any, k: int) -> Any:
    if k in (3, 40):
        msg.linear_acceleration.x = np.nan
    return msg


def _zero_cloud(msg: Any, _: int) -> Any:
    msg.data = np.zeros_like(msg.data)
    return msg


def _late_stamp(msg: Any, k: int) -> Any:
    """Message 10 stamped 30 ms late: after message 11 (wheel speeds come at 50 Hz)."""
    if k == 10:
        ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec + 30_000_000
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return msg


def _with(context: Any, run: Callable[[], Run]) -> Run:
    with context:
        return run()


def case_18_weak_spots(ws: Workspace) -> Outcome:
    """info on NaN IMU samples and on all-zero clouds; reversed stamps noted in the result;
    an empty log folder; duplicate YAML keys and negative voxel sizes; a newline in a file name."""
    nan_imu = rewrite_log(ws.sim_log, ws.path("nan_imu.mcap"), {"/ouster/imu": _nan_imu_sample})
    zero_cloud = rewrite_log(ws.sim_log, ws.path("zero_cloud.mcap"), {"/ouster/points": _zero_cloud})
    swapped = rewrite_log(ws.sim_log, ws.path("swapped.mcap"), {"/wheel_speeds": _late_stamp})
    dup = ws.path("dup.yaml")
    dup.write_text("robot:\n  mass_kg: 1000\n  mass_kg: 2000\n")
    empty = ws.path("empty")
    empty.mkdir()
    locked_logs = ws.path("locked_logs")
    (locked_logs / "locked").mkdir(parents=True)
    shutil.copy(ws.sim_log, locked_logs / "s.mcap")
    real_scandir = os.scandir

    def scandir(path: Any = ".") -> Any:  # as if `locked` were mode 000 (root reads anything)
        if Path(path).name == "locked":
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_scandir(path)
    newline_tum = ws.path("est\nfake row.tum")
    gt_tum = ws.sim_log.with_name("s.gt.tum")
    shutil.copy(gt_tum, newline_tum)
    checks = {
        "info NaN IMU": cli("info", nan_imu, "--json"),
        "info zero cloud": cli("info", zero_cloud, "--json"),
        "replay swapped stamps": cli("control", swapped, "--mode", "replay", "--out", ws.path("R"), "--json"),
        "empty log folder": cli("nightly", empty, "--out", ws.path("N")),
        "unreadable folder": _with(mock.patch("os.scandir", scandir), lambda: cli(
            "nightly", locked_logs, "--out", ws.path("N2"), "--jobs", 1, "--no-pdf", "--since", "2100-01-01")),
        "duplicate key": cli("config", "--config", dup),
        "negative voxel": cli("config", "--set", "slam.matching.surf_leaf_m=-0.4"),
        "newline file name": cli("ape", gt_tum, newline_tum),
    }
    info_imu = json.loads(checks["info NaN IMU"].out)["results"][0]
    info_cloud = json.loads(checks["info zero cloud"].out)["results"][0]
    replay = json.loads(checks["replay swapped stamps"].out)
    good = {
        "info NaN IMU": any(f["level"] == "warning" and "dropped" in f["message"] for f in info_imu["findings"]),
        "info zero cloud": any(f["level"] == "error" and "no valid point" in f["message"]
                               for f in info_cloud["findings"]),
        "replay swapped stamps": any("out-of-order" in w for w in replay["warnings"]),
        "empty log folder": checks["empty log folder"].code == 4,
        "unreadable folder": checks["unreadable folder"].code == 3 and "locked" in checks["unreadable folder"].err,
        "duplicate key": checks["duplicate key"].code == 2 and "duplicate key" in checks["duplicate key"].err,
        "negative voxel": checks["negative voxel"].code == 2,
        "newline file name": checks["newline file name"].code == 0
        and not any(ln.startswith("fake row") for ln in checks["newline file name"].out.splitlines()),
    }
    codes = {k: r.code for k, r in checks.items()}
    return Outcome("18", _cmd("info / control / nightly EMPTY / config DUP / ape 'est\\nfake row.tum'"),
                   max(codes.values()), 4, all(good.values()),
                   ", ".join(f"{k}: exit {codes[k]}{'' if good[k] else ' (WRONG)'}" for k in checks),
                   [(k, codes[k], good[k]) for k in checks])


CASES: list[Callable[[Workspace], Outcome]] = [
    case_01a_simulate_into_user_folder, case_01b_simulate_dot, case_01c_simulate_over_recording,
    case_02a_slam_same_log_name, case_02b_control_same_second, case_03_nan_wheel_speeds,
    case_04_lidar_frame_mismatch, case_05_impossible_latitude, case_06_zero_quaternions, case_07_bad_parameters,
    case_08_no_gnss_fix, case_09_nan_rotations, case_10a_out_is_a_file, case_10b_read_only_out,
    case_10c_disk_full, case_11_nightly_disk_full, case_11b_history_rollback, case_12_bad_config_values,
    case_13_alias_bomb, case_14_umask_permissions, case_15_forged_topic, case_16_non_ascii_ids,
    case_17_impossible_date, case_18_weak_spots,
]


def run_all() -> list[Outcome]:
    with tempfile.TemporaryDirectory(prefix="mrnc-reliability-") as tmp:
        base = Path(tmp)
        (base / "sim").mkdir()
        sim_log = make_sim_log(base / "sim")
        outcomes = []
        for k, case in enumerate(CASES):
            root = base / f"case{k:02d}"
            root.mkdir()
            o = case(Workspace(root, sim_log))
            outcomes.append(replace(o, detail=o.detail.replace(str(root), "TMP").replace(str(base), "TMP")))
        return outcomes


def markdown(outcomes: list[Outcome]) -> str:
    rows = ["| # | command | exit | expected | harm avoided | detail |", "|---|---|---|---|---|---|"]
    for o in outcomes:
        detail = o.detail.replace("|", "/").replace("\n", " ")[:170]
        rows.append(f"| {o.case} | `{o.command.replace('|', '/')}` | {o.code} | {o.expected} | "
                    f"{'yes' if o.harm_avoided else 'NO'} | {detail} |")
        rows += [f"| {o.case}.{k + 1} | {name} | {code} | | {'yes' if right else 'NO'} | |"
                 for k, (name, code, right) in enumerate(o.parts)]
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    sys.stdout.write(markdown(run_all()))
