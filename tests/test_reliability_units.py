"""Unit checks of the issue-15 mechanisms the CLI cases rely on: stable ids, run folders that
never collide or replace foreign files, the umask, the sanitisers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from markupsafe import Markup

from mrnc_eval.errors import OutputError
from mrnc_eval.results import RunResult, atomic_write_text, new_run_dir, stable_id, write_result
from mrnc_eval.text import printable, shorten


def test_stable_ids_are_ascii_readable_and_depend_only_on_their_own_path() -> None:
    assert stable_id("nested/b.bag") == "nested_b"  # plain names keep their readable id
    assert stable_id("run_01.mcap") == "run_01"
    ids = {stable_id(name) for name in ("Übung.mcap", "Ölfeld.mcap", "Ähre.mcap", "日本.mcap", "中国.mcap")}
    assert len(ids) == 5
    assert all(i.isascii() for i in ids)
    assert stable_id("Übung.mcap").startswith("Ubung-")
    assert stable_id("日本.mcap") == stable_id("日本.mcap")  # a hash of the path, not of the order seen


def test_new_run_dirs_never_collide(tmp_path: Path) -> None:
    names = {new_run_dir(tmp_path, "run", "slam-lio").name for _ in range(200)}
    assert len(names) == 200


def test_write_result_replaces_only_results(tmp_path: Path) -> None:
    target = tmp_path / "mine"
    target.mkdir()
    (target / "notes.txt").write_text("user data")
    with pytest.raises(OutputError, match="did not write"):
        write_result(RunResult(kind="info", log_path="x", log_id="x"), target, "a: 1\n")
    assert (target / "notes.txt").read_text() == "user data"
    assert [p.name for p in tmp_path.iterdir()] == ["mine"]  # no partial folder left behind
    run = write_result(RunResult(kind="info", log_path="x", log_id="x"), tmp_path / "run", "a: 1\n")
    write_result(RunResult(kind="info", log_path="y", log_id="y"), run, "a: 2\n")  # an earlier result: replaced
    assert "y" in (run / "result.json").read_text()


def test_files_and_folders_follow_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a.html", "x")
        run = write_result(RunResult(kind="info", log_path="x", log_id="x"), tmp_path / "run", "a: 1\n")
    finally:
        os.umask(old)
    assert (tmp_path / "a.html").stat().st_mode & 0o777 == 0o640
    assert run.stat().st_mode & 0o777 == 0o750
    assert (run / "result.json").stat().st_mode & 0o777 == 0o640


def test_one_sanitiser_for_terminal_and_html() -> None:
    from mrnc_eval.reports.render import environment

    hostile = "/gnss\nERROR forged \x1b[31m<script>"
    assert "\n" not in printable(hostile)
    assert "\x1b" not in printable(hostile)
    html = environment().from_string("{{ t }}{{ m }}").render(t=hostile, m=Markup("<b>ours</b>"))
    assert "\x1b" not in html
    assert "&lt;script&gt;" in html
    assert "<b>ours</b>" in html
    assert len(shorten(list(range(10**6)))) <= 200


def test_force_replaces_only_a_log_this_tool_wrote(tmp_path: Path) -> None:
    from mrnc_eval.commands.simulate import check_target

    ours = tmp_path / "sim.mcap"
    ours.write_bytes(b"log")
    (tmp_path / "sim.gt.tum").write_text("1 0 0 0 0 0 0 1\n")
    with pytest.raises(OutputError, match="already exists"):
        check_target(ours, force=False)
    check_target(ours, force=True)  # a log with its ground truth beside it: ours, replaceable
    bag_dir = tmp_path / "bag"
    bag_dir.mkdir()
    (bag_dir / "metadata.yaml").write_text("x")
    (bag_dir / "bag_0.mcap").write_bytes(b"x")
    (tmp_path / "bag.gt.tum").write_text("1 0 0 0 0 0 0 1\n")
    check_target(bag_dir, force=True)
    (bag_dir / "notes.txt").write_text("mine")  # anything else inside: never replaced
    with pytest.raises(OutputError, match="not a log this tool wrote"):
        check_target(bag_dir, force=True)
    check_target(tmp_path / "new.mcap", force=False)  # a new name is fine


def test_the_latest_link_never_replaces_a_users_file(tmp_path: Path) -> None:
    from mrnc_eval.results import link_latest

    (tmp_path / "latest").write_text("my notes")
    run = tmp_path / "run-1"
    run.mkdir()
    link_latest(run)
    assert (tmp_path / "latest").read_text() == "my notes"
