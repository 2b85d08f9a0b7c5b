"""Every verb's --json prints one document of one shape (commands/output.py), validated against
the JSON Schema shipped in the package: scripts read `results` (a list) and each item's `stats`."""

from __future__ import annotations

import json

import jsonschema
import pytest

from mrnc_eval.cli import main
from mrnc_eval.commands.output import SCHEMA_FILE, item, schema


def _json_of(capsys, argv: list[str]) -> dict:
    capsys.readouterr()
    code = main(argv)
    out = capsys.readouterr().out
    assert code == 0, out
    return json.loads(out)


def test_every_verb_prints_one_schema_valid_shape(sim_runs, tmp_path, capsys):
    log, slam_dir = str(sim_runs.log), str(sim_runs.slam)
    gt = str(sim_runs.log.with_suffix(".gt.tum"))
    runs = {
        "info": ["info", log, "--json"],
        "slam": ["slam", log, "--out", str(tmp_path / "s"), "--json"],
        "control replay": ["control", log, "--mode", "replay", "--out", str(tmp_path / "c"), "--json"],
        "control sweep": ["control", "--mode", "sweep", "--runs", "2", "--controllers", "raid,ff",
                          "--out", str(tmp_path / "w"), "--json"],
        "ape": ["ape", gt, f"{slam_dir}/trajectory.tum", f"{slam_dir}/trajectory_online.tum", "--max-diff", "0.02",
                "--json", "--decompose"],
        "rpe": ["rpe", gt, f"{slam_dir}/trajectory.tum", "--max-diff", "0.02", "--json", "--drift"],
        "table": ["table", str(sim_runs.root), "--json"],
    }
    validator = jsonschema.Draft202012Validator(schema())
    seen = {}
    for label, argv in runs.items():
        doc = _json_of(capsys, argv)
        errors = sorted(validator.iter_errors(doc), key=str)
        assert not errors, f"{label}: {errors[0].message} at {list(errors[0].absolute_path)}"
        assert doc["verb"] == argv[0], label
        assert doc["results"], label
        seen[label] = doc
    # the numbers scripts want sit under each item's stats
    assert seen["ape"]["results"][0]["stats"]["rmse"] > 0
    assert len(seen["ape"]["results"]) == 2
    assert "mean_trans_pct" in seen["rpe"]["results"][0]["drift"]
    assert seen["slam"]["results"][0]["stats"]["ape_rmse_m"] > 0
    assert seen["info"]["results"][0]["stats"]["duration_s"] > 5
    assert {r["controller"] for r in seen["control sweep"]["results"]} == {"raid", "ff"}
    assert any(r["stats"]["value"] is not None for r in seen["table"]["results"])


def test_schema_refuses_the_old_shapes():
    """Negative control: the shapes verbs printed before (a bare list; stats at the top) fail."""
    validator = jsonschema.Draft202012Validator(schema())
    assert not validator.is_valid([{"name": "est", "rmse": 0.1}])
    assert not validator.is_valid({"schema_version": 1, "verb": "ape", "results": {"est": {"rmse": 0.1}},
                                   "meta": {}, "warnings": []})
    assert not validator.is_valid({"schema_version": 1, "verb": "ape", "meta": {}, "warnings": [],
                                   "results": [{"name": "est", "stats": {"rmse": "0.1"}}]})


def test_schema_ships_in_the_package():
    assert SCHEMA_FILE.is_file()
    assert SCHEMA_FILE.parent.name == "schemas"
    with pytest.raises(TypeError, match="non-numbers"):
        item("x", {"label": "RAID"})
