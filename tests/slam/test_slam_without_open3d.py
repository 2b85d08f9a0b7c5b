"""A SLAM run imports only what it uses: with open3d refused by the import system it still closes
loops (slam/icp.py) and writes map.ply and map.pcd (io/ply.py, io/pcd.py), and it imports neither
open3d nor the report stack (matplotlib, pandas, weasyprint, dask), nor scipy, numba or llvmlite (the
SLAM's kernels are C: slam/_prep_kernels.c, slam/_match_kernels.c), nor the report renderer or
pydantic. The same block makes `simulate`,
which does need open3d (ray casting), fail: the negative control that the block works."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

from mrnc_eval.io.ply import read_ply_xyz
from mrnc_eval.io.scan_folder import _read_pcd
from mrnc_eval.results import read_result

REPO = Path(__file__).resolve().parents[2]
LOG = REPO / "sample_logs" / "loop_forest.bag"
BLOCKED = ("open3d",)
# scipy: the SLAM's rotations are geometry/rotation.py's; numba and llvmlite: its kernels are C; markupsafe,
# jinja2: the gates a run exits on are judged by reports/gates.py, not the report renderer; pydantic: a plain
# command line skips typer's validators (cli_fast)
NOT_IN_A_SLAM_RUN = ("open3d", "matplotlib", "pandas", "weasyprint", "dask", "scipy", "numba", "llvmlite",
                     "markupsafe", "jinja2", "pydantic")

SCRIPT = textwrap.dedent("""
    import importlib.abc, json, sys
    BLOCKED = {blocked!r}

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}} (blocked)", name=name)
            return None

    sys.meta_path.insert(0, Block())
    from mrnc_eval.cli import main
    codes, loaded = {{}}, {{}}
    for key, argv in json.loads(sys.argv[1]).items():
        codes[key] = main(argv)
        loaded[key] = sorted(({{m.split(".")[0] for m in sys.modules}} | set(sys.modules)) & set({watch!r}))
    print(json.dumps({{"codes": codes, "loaded": loaded}}))
""").format(blocked=BLOCKED, watch=NOT_IN_A_SLAM_RUN)


def test_slam_run_without_open3d_closes_loops_and_writes_the_map(tmp_path: Path) -> None:
    commands = {"slam": ["slam", str(LOG), "--end", "45", "--out", str(tmp_path / "slam")],
                "simulate": ["simulate", str(tmp_path / "sim.mcap")]}  # after slam: its import must not leak back
    env = {"PYTHONPATH": str(REPO), "HOME": str(tmp_path), "PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(commands)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["codes"]["slam"] == 0, proc.stderr[-3000:]
    assert out["loaded"]["slam"] == []  # nothing of the viewer or report stack was imported by the run
    (run,) = (p for p in (tmp_path / "slam").iterdir() if p.name != "latest")
    assert read_result(run).metric("loop_closures").value > 0  # the loop-closure ICP ran (measured 10 by 45 s)
    ply, pcd = read_ply_xyz(run / "map.ply"), _read_pcd(run / "map.pcd")[0]
    assert len(ply) > 1000
    np.testing.assert_array_equal(pcd, ply.astype(np.float32))
    # negative control: the block does refuse open3d to a verb that needs it
    assert out["codes"]["simulate"] == 2
    assert "open3d" in proc.stderr
    assert not (tmp_path / "sim.mcap").exists()
