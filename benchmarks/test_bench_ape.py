"""APE end to end (files -> statistics) on a 1,000,000-pose TUM pair: our CLI vs evo's CLI.

Each run is a fresh process under /usr/bin/time (wall time and peak RSS of the process), in
the same session, ours before and after evo so that load from other processes on a shared
machine is averaged rather than hitting one side only. Cases: translation (SE(3)
alignment) and rotation angle in degrees. Targets (issue 14): >= 30x faster than evo on
translation, >= 100x on angle_deg, peak memory <= 1/4 of evo's; the RMSE equal to 1e-9.
Run: PYTHONPATH=. .venv/bin/python -m pytest -m benchmark benchmarks/test_bench_ape.py -s
(the C reader of io/number_table must be built: `pip install -e .` does it in place).
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.benchmark

N = 1_000_000
TARGET_SPEEDUP = {"trans": 30.0, "angle_deg": 100.0}
EVO_RELATION = {"trans": "trans_part", "angle_deg": "angle_deg"}


def _write_pair(d: Path, n: int = N) -> tuple[Path, Path]:
    """100 Hz ground truth and an offset, noisy estimate 3 ms late (6 and 9 decimals)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    t = np.arange(n) / 100.0
    pos = np.stack([50 * np.sin(t / 500), 30 * np.sin(t / 250), np.sin(t / 100)], axis=1)
    rot = Rotation.from_euler("z", t[:, None] / 50)
    off = Rotation.from_euler("zyx", [0.3, 0.01, -0.02])
    est_pos = off.apply(pos + rng.normal(scale=0.05, size=pos.shape)) + [2.0, -1.0, 0.3]
    est_rot = (off * rot * Rotation.from_rotvec(rng.normal(scale=0.01, size=(n, 3)))).as_quat()
    fmt = "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f"
    np.savetxt(d / "ref.tum", np.c_[t, pos, rot.as_quat()], fmt=fmt)
    np.savetxt(d / "est.tum", np.c_[t + 0.003, est_pos, est_rot], fmt=fmt)
    return d / "ref.tum", d / "est.tum"


def _timed(cmd: list[str], home: Path) -> tuple[float, float, str]:
    """(wall s, peak RSS MB, stdout) of a fresh process."""
    env = {"HOME": str(home), "PATH": os.environ.get("PATH", "/usr/bin:/bin"), "MPLBACKEND": "Agg",
           "PYTHONPATH": os.environ.get("PYTHONPATH", "")}
    out = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", *cmd], capture_output=True, text=True, check=True,
                         env=env)
    wall, rss_kb = re.findall(r"TIME ([\d.]+) (\d+)", out.stderr)[-1]
    return float(wall), int(rss_kb) / 1024, out.stdout


def ours(ref: Path, est: Path, relation: str, home: Path) -> tuple[float, float, float]:
    wall, rss, out = _timed([sys.executable, "-m", "mrnc_eval", "ape", str(ref), str(est), "--align", "se3",
                             "--relation", relation, "--json"], home)
    return wall, rss, float(json.loads(out)[0]["rmse"])


def evo(ref: Path, est: Path, relation: str, home: Path) -> tuple[float, float, float]:
    evo_ape = Path(sys.executable).with_name("evo_ape")
    cmd = [str(evo_ape), "tum", str(ref), str(est), "-a", "-r", EVO_RELATION[relation], "--no_warnings"]
    wall, rss, out = _timed(cmd, home)
    return wall, rss, float(re.search(r"rmse\s+([\d.eE+-]+)", out).group(1))


@pytest.mark.parametrize("relation", ["trans", "angle_deg"])
def test_ape_1m_poses_vs_evo(tmp_path_factory: pytest.TempPathFactory, relation: str) -> None:
    tmp_path = tmp_path_factory.getbasetemp() / "bench_ape"
    tmp_path.mkdir(exist_ok=True)
    if shutil.which("evo_ape", path=str(Path(sys.executable).parent)) is None:
        pytest.fail("evo is not installed (pip install 'mrnc-eval[test]'): the benchmark has no peer")
    if importlib.util.find_spec("mrnc_eval.io._numtext") is None:
        pytest.fail("mrnc_eval/io/_numtext.c is not built (pip install -e .): the benchmark would time the "
                    "strict text path")
    ref, est = tmp_path / "ref.tum", tmp_path / "est.tum"
    if not est.exists():
        _write_pair(tmp_path)
    ours(tmp_path / "ref.tum", tmp_path / "ref.tum", relation, tmp_path)  # warms the page cache, untimed
    before = ours(ref, est, relation, tmp_path)
    theirs = evo(ref, est, relation, tmp_path)
    after = ours(ref, est, relation, tmp_path)
    wall = (before[0] + after[0]) / 2
    rss = max(before[1], after[1])
    speedup, memory = theirs[0] / wall, rss / theirs[1]
    print(f"\nAPE {relation} 1e6 poses, files -> statistics, SE(3): ours {before[0]:.2f} / {after[0]:.2f} s "
          f"(mean {wall:.2f} s), {rss:.0f} MB peak; evo {theirs[0]:.2f} s, {theirs[1]:.0f} MB peak; "
          f"speed-up {speedup:.1f}x, memory {memory:.2f} of evo's; rmse ours {before[2]:.9g} evo {theirs[2]:.9g}")
    assert before[2] == pytest.approx(theirs[2], abs=5e-7)  # evo prints 6 decimals
    assert speedup >= TARGET_SPEEDUP[relation]
    assert memory <= 0.25
