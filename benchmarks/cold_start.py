"""Cold start against kiss-icp: each run from a dropped page cache (the interpreter, the libraries,
the log and the scans all read from disk), the two sides alternating, three rounds, medians.

Two pairs, both printed:
- the whole run (issue 30's "cold start" of the run it times warm): `mrnc-eval slam LOG` mapping
  every sweep against `kiss_icp_pipeline` on the same log's clouds as .bin scans;
- the start-up alone: `slam LOG --end 0.25` against `kiss_icp_pipeline` on the first two scans.

    sudo-capable shell: PYTHONPATH=. .venv/bin/python -m benchmarks.cold_start LOG [--rounds 3]
        [--python /tmp/coldvenv/bin/python]

Dropping the cache needs root (`echo 3 > /proc/sys/vm/drop_caches`); without it the script stops and
says so (`--warm` times warm runs instead, labelled as such). On a shared machine a library another
process keeps mapped stays cached: give `--python` a fresh copy of the venv (`cp -a .venv DIR`), whose
files no other process maps. The load average is printed beside every row.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

TIME = "/usr/bin/time"
KISS = "import sys; from kiss_icp.tools.cmd import run; sys.argv = ['kiss_icp_pipeline', sys.argv[1]]; run()"


def drop_page_cache() -> None:
    os.sync()
    try:
        Path("/proc/sys/vm/drop_caches").write_text("3\n")
    except OSError as exc:
        raise SystemExit(f"cannot drop the page cache ({exc}): run as root, or pass --warm") from exc


def timed(cmd: list[str], cwd: Path) -> tuple[float, float, float]:
    """Wall s, CPU s (user + system, all threads) and peak MB of one command, by /usr/bin/time."""
    stamp = cwd / "time.txt"
    proc = subprocess.run([TIME, "-f", "%e %U %S %M", "-o", str(stamp), *cmd], cwd=cwd,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    wall, user, system, peak_kb = stamp.read_text().split()[-4:]
    return float(wall), float(user) + float(system), int(peak_kb) / 1e3


def scans_folder(log: Path, folder: Path) -> Path:
    """The log's clouds as KITTI-style .bin scans (float32 x, y, z, intensity), kiss_icp_pipeline's input."""
    import numpy as np

    from mrnc_eval.io import open_log

    folder.mkdir(parents=True, exist_ok=True)
    with open_log(log) as lg:
        for k, sweep in enumerate(lg.sweeps()):
            inten = sweep.intensity if sweep.intensity is not None else np.zeros(len(sweep.points), np.float32)
            np.c_[sweep.points, inten].astype(np.float32).tofile(folder / f"{k:06d}.bin")
    return folder


def commands(python: str, log: Path, scans: Path, first_two: Path, out: Path) -> dict[str, list[str]]:
    slam = [python, "-m", "mrnc_eval", "slam", str(log), "--out", str(out)]
    return {"lio, whole run": slam, "kiss_icp_pipeline, whole run": [python, "-c", KISS, str(scans)],
            "lio, start-up (--end 0.25)": [*slam, "--end", "0.25"],
            "kiss_icp_pipeline, start-up (two scans)": [python, "-c", KISS, str(first_two)]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--python", default=sys.executable, help="the interpreter both sides run with")
    ap.add_argument("--warm", action="store_true", help="do not drop the page cache (warm runs)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="cold_start_") as tmp:  # the scans: ~0.4 GB for forest30
        work = Path(tmp)
        scans = scans_folder(args.log, work / "scans")
        first_two = work / "scans2"
        first_two.mkdir()
        for f in sorted(scans.iterdir())[:2]:
            (first_two / f.name).write_bytes(f.read_bytes())
        cmds = commands(args.python, args.log.resolve(), scans, first_two, work / "out")
        rows: dict[str, list[tuple[float, float, float, float]]] = {name: [] for name in cmds}
        for _ in range(args.rounds):
            for name, cmd in cmds.items():
                if not args.warm:
                    drop_page_cache()
                load = os.getloadavg()[0]
                rows[name].append((*timed(cmd, work), load))
    print(f"{'warm' if args.warm else 'page cache dropped before each run'}, {args.rounds} alternating rounds, "
          f"log {args.log}, python {args.python}\n")
    print("| run | wall s (rounds) | median wall s | median CPU s | peak MB | load |\n|---|---|---|---|---|---|")
    med = {name: statistics.median(r[0] for r in runs) for name, runs in rows.items()}
    for name, runs in rows.items():
        walls = " / ".join(f"{r[0]:.2f}" for r in runs)
        print(f"| {name} | {walls} | {med[name]:.2f} | {statistics.median(r[1] for r in runs):.2f} | "
              f"{max(r[2] for r in runs):.0f} | {min(r[3] for r in runs):.1f}-{max(r[3] for r in runs):.1f} |")
    print(f"\nwhole run: lio / kiss_icp_pipeline = {med['lio, whole run'] / med['kiss_icp_pipeline, whole run']:.2f}; "
          f"start-up: {med['lio, start-up (--end 0.25)'] / med['kiss_icp_pipeline, start-up (two scans)']:.2f} "
          "(below 1: lio starts faster)")


if __name__ == "__main__":
    main()
