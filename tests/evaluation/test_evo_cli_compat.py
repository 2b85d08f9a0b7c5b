"""evo's own command lines, with `evo_ape`/`evo_rpe` replaced by `mrnc-eval ape`/`rpe`, give evo's
numbers on the same files; `evo_res` loads our --save_results zip; `compare` and the API read evo's.

evo runs as its own commands (subprocesses, HOME set by conftest), each writing --save_results;
ours run the same argument list through cli.main and write theirs. The two zips are compared
statistic by statistic and array by array (evo's arrays, our reader: no pickle)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.io.evo_results import read_evo_zip
from mrnc_eval.io.trajectory_files import write_tum
from tests.evaluation.evo_reference import make_pair, require_evo
from tests.needs import missing

BIN = Path(sys.executable).parent

APE_CASES = {  # evo's flags, as a user types them
    "default": [],
    "a": ["-a"],
    "as": ["-as"],
    "s": ["-s"],
    "align_origin": ["--align_origin"],
    "angle_deg": ["-a", "-r", "angle_deg"],
    "t_max_diff": ["-a", "--t_max_diff", "0.002"],
    "t_offset": ["-a", "--t_offset", "-0.003"],
    "n_to_align": ["--align", "--correct_scale", "--n_to_align", "150"],
    "pose_relation_full": ["--pose_relation", "full", "-a", "--project_to_plane", "xy"],
}
RPE_CASES = {
    "default": [],
    "d10_frames": ["-d", "10", "-u", "f", "-r", "angle_deg"],
    "metres_all_pairs": ["-d", "2", "-u", "m", "--all_pairs", "-as"],
    "t_offset": ["-a", "--t_offset", "-0.003", "-r", "point_distance", "--n_to_align", "200"],
}


def _evo(tool: str, args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    exe = BIN / tool
    if not exe.exists():
        found = shutil.which(tool)
        if found is None:
            missing(f"{tool} is not installed (pip install 'mrnc-eval[test]')")
        exe = Path(found)
    return subprocess.run([str(exe), *args], cwd=cwd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "MPLBACKEND": "Agg"}, check=False)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    require_evo()
    d = tmp_path_factory.mktemp("evo_cli")
    ref, est = make_pair(n=900, seed=3)
    write_tum(d / "gt.tum", ref)
    write_tum(d / "est.tum", est)
    jobs = [("evo_ape", name, args) for name, args in APE_CASES.items()] + \
           [("evo_rpe", name, args) for name, args in RPE_CASES.items()]

    def run(job: tuple[str, str, list[str]]) -> None:
        tool, name, args = job
        r = _evo(tool, ["tum", "gt.tum", "est.tum", *args, "--save_results", f"evo_{tool}_{name}.zip",
                        "--silent"], d)
        assert r.returncode == 0, (tool, args, r.stderr[-2000:])

    # evo creates its settings folder (~/.evo) on first start without exist_ok: two first starts
    # at once race on the mkdir, so one command runs alone before the rest go two at a time.
    run(jobs[0])
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(run, jobs[1:]))
    return d


def _ours(verb: str, name: str, args: list[str], d: Path) -> Path:
    out = d / f"ours_{verb}_{name}.zip"
    out.unlink(missing_ok=True)
    cwd = Path.cwd()
    os.chdir(d)  # evo's command line names the files relative to the working folder
    try:
        assert main([verb, "tum", "gt.tum", "est.tum", *args, "--save_results", out.name]) == 0
    finally:
        os.chdir(cwd)
    return out


def _assert_same(ours: Path, theirs: Path) -> None:
    a, b = read_evo_zip(ours), read_evo_zip(theirs)
    assert a.info == b.info  # title with the alignment note, names, label
    assert a.stats.keys() == b.stats.keys()
    for k, v in b.stats.items():
        assert a.stats[k] == pytest.approx(v, rel=1e-12 if k == "sse" else 1e-9, abs=1e-12), k
    skip = {"alignment_transformation_sim3"} if "(scale corrected)" in b.title else set()  # see below
    assert a.arrays.keys() == b.arrays.keys()
    for k in b.arrays.keys() - skip:
        np.testing.assert_allclose(a.arrays[k], b.arrays[k], rtol=1e-10, atol=1e-12, err_msg=k)


@pytest.mark.parametrize("name", list(APE_CASES))
def test_evo_ape_command_gives_evos_numbers(files: Path, name: str) -> None:
    # -s alone: evo stores Umeyama's full sim(3) though it applies only the scale; ours stores the
    # scale it applied (diag(c)). Every error and statistic agrees.
    _assert_same(_ours("ape", name, APE_CASES[name], files), files / f"evo_evo_ape_{name}.zip")


@pytest.mark.parametrize("name", list(RPE_CASES))
def test_evo_rpe_command_gives_evos_numbers(files: Path, name: str) -> None:
    _assert_same(_ours("rpe", name, RPE_CASES[name], files), files / f"evo_evo_rpe_{name}.zip")


def test_the_default_is_evos_and_a_changed_alignment_changes_the_number(files: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Negative control: the numbers above are not alignment-blind; the first line names the alignment."""
    default = read_evo_zip(_ours("ape", "default", [], files))
    aligned = read_evo_zip(files / "evo_evo_ape_a.zip")
    assert default.stats["rmse"] > 10 * aligned.stats["rmse"]
    capsys.readouterr()
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum")]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "not aligned" in first
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum"), "-as", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["results"][0]["alignment"]["mode"] == "sim3"
    assert "Sim(3)" in doc["meta"]["title"]
    assert doc["results"][0]["stats"]["rmse"] == pytest.approx(
        read_evo_zip(files / "evo_evo_ape_as.zip").stats["rmse"], rel=1e-12)


def test_evo_res_loads_our_zip_beside_evos(files: Path) -> None:
    ours = _ours("ape", "res", ["-a"], files)
    r = _evo("evo_res", [str(ours), str(files / "evo_evo_ape_a.zip"), "--use_filenames", "--no_warnings",
                         "--save_table", str(files / "res.csv")], files)
    assert r.returncode == 0, r.stderr[-2000:]
    table = (files / "res.csv").read_text()
    rmse = read_evo_zip(files / "evo_evo_ape_a.zip").stats["rmse"]
    assert table.count(f"{rmse:.6f}"[:7]) >= 2, table  # both rows carry evo's RMSE


def test_save_results_refuses_to_overwrite_and_to_hold_two_estimates(files: Path) -> None:
    target = files / "kept.zip"
    target.write_bytes(b"not ours")
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum"), "--save_results", str(target)]) == 4
    assert target.read_bytes() == b"not ours"
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum"), str(files / "est.tum"),
                 "--save_results", str(files / "two.zip")]) == 2
    assert not (files / "two.zip").exists()


def test_evo_spellings_that_conflict_are_refused(files: Path) -> None:
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum"), "-a", "--align_origin"]) == 2
    assert main(["ape", str(files / "gt.tum"), str(files / "est.tum"), "-a", "--align", "sim3"]) == 2


def test_compare_and_api_read_evo_zips(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mrnc_eval import api

    evo_a, evo_as = files / "evo_evo_ape_a.zip", files / "evo_evo_ape_as.zip"
    res = api.load_evo_result(evo_a)
    assert res.info["label"] == "APE (m)"
    assert res.arrays["error_array"].shape == (900,)
    capsys.readouterr()
    assert main(["compare", str(evo_a), str(evo_as), "--format", "markdown"]) == 0
    out = capsys.readouterr().out
    rmse_a, rmse_as = res.stats["rmse"], api.load_evo_result(evo_as).stats["rmse"]
    assert "APE (m)/rmse" in out
    assert f"{rmse_a:.4f}" in out
    assert f"{rmse_as:.4f}" in out
    assert "Sim(3)" in out  # the titles differ: shown as a differing setting


def test_an_evo_zip_is_never_unpickled(files: Path) -> None:
    """An object array would run code through pickle when loaded naively; it is refused."""
    import io
    import zipfile

    from mrnc_eval.errors import InputError

    bad = files / "pickled.zip"
    buf = io.BytesIO()
    np.save(buf, np.array([{"x": 1}], dtype=object), allow_pickle=True)
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("info.json", json.dumps({"title": "t", "label": "APE (m)"}))
        z.writestr("stats.json", json.dumps({"rmse": 1.0}))
        z.writestr("error_array.npy", buf.getvalue())
    with pytest.raises(InputError, match="not a plain numeric array"):
        read_evo_zip(bad)
    assert main(["compare", str(bad), str(files / "evo_evo_ape_a.zip")]) == 4
