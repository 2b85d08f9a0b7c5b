"""`ape --plot` with several estimates: labels as given (--label), every text box inside the
figure and no two titles or legends on top of each other, checked on the drawn layout."""

from __future__ import annotations

import json
from dataclasses import replace
from itertools import combinations
from pathlib import Path

import pytest

from mrnc_eval.cli import main
from mrnc_eval.evaluation.ape import ape
from mrnc_eval.io.trajectory_files import write_tum
from mrnc_eval.reports.figures import ape_path_figure, draw_error_path, new_figure, wrapped
from tests.evaluation.evo_reference import make_pair

LONG = "results/loop_forest-slam-kiss-icp-20261126T023526Z-737c26/trajectory_online.tum"


def _boxes(fig):
    """After drawing: each visible axes' tight box (its drawn tick labels, axis labels, title,
    legend; colour bars are axes too), the legends' and the titles' boxes (px)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.legend import Legend

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    axes = [(ax.get_title() or ax.get_ylabel() or "axes", ax.get_tightbbox(renderer)) for ax in fig.axes
            if ax.get_visible()]
    legends = [lg.get_window_extent(renderer) for lg in fig.findobj(Legend) if lg.get_visible()]
    titles = [ax.title.get_window_extent(renderer) for ax in fig.axes if ax.get_visible() and ax.get_title()]
    if fig._suptitle is not None:
        axes.append((fig._suptitle.get_text(), fig._suptitle.get_window_extent(renderer)))
        titles.append(fig._suptitle.get_window_extent(renderer))
    return fig.bbox, axes, legends, titles


def _layout_problems(fig) -> list[str]:
    frame, boxes, legends, titles = _boxes(fig)

    def outside(b) -> bool:
        return b.x0 < frame.x0 - 1 or b.x1 > frame.x1 + 1 or b.y0 < frame.y0 - 1 or b.y1 > frame.y1 + 1

    problems = [f"{label!r} leaves the figure" for label, b in boxes if outside(b)]
    problems += ["a legend leaves the figure" for b in legends if outside(b)]
    problems += ["two titles overlap" for a, b in combinations(titles, 2) if a.overlaps(b)]
    problems += ["two legends overlap" for a, b in combinations(legends, 2) if a.overlaps(b)]
    return problems


def _results(names: list[str]):
    ref, est = make_pair(n=400, seed=4)
    return [replace(ape(ref, est, max_diff=0.01), name=n) for n in names]


@pytest.mark.parametrize("names", [["LIO (ours)", "kiss-icp"], [LONG, LONG.replace("kiss-icp", "lio"), "odom"]])
def test_ape_plot_text_stays_inside_and_apart(names: list[str]) -> None:
    fig = ape_path_figure(_results(names), "APE w.r.t. translation part (m) (se3 alignment)")
    assert _layout_problems(fig) == []
    shown = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert [t.replace("\n", "") for t in shown] == names  # each panel titled with its label, nothing cut


def test_the_old_layout_fails_the_same_check() -> None:
    """Negative control: long names as unwrapped titles side by side, legends inside with the
    name in them (the layout before) leave the figure and overlap."""
    results = _results([LONG, LONG])
    fig, axes = new_figure(6.0 * 2, 5.0, 1, 2)
    for ax, r in zip(axes[0], results, strict=True):
        draw_error_path(fig, ax, r.ref_xyz, r.est_xyz, r.errors, est_label=f"{r.name} (se3 aligned)", title=r.name)
    fig.suptitle("APE")
    problems = _layout_problems(fig)
    assert any("leaves the figure" in p for p in problems), problems


def test_wrapped_breaks_paths_at_separators_and_keeps_every_character() -> None:
    lines = wrapped(LONG, 4.0).split("\n")
    assert len(lines) > 1
    assert "".join(lines) == LONG
    assert all(len(line) <= 36 for line in lines)


def test_label_names_each_estimate_in_table_json_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, est = make_pair(n=300, seed=5)
    write_tum(tmp_path / "gt.tum", ref)
    run = tmp_path / "results" / "forest-slam-lio-20261126T000000Z-abc123"
    run.mkdir(parents=True)
    write_tum(run / "trajectory.tum", est)
    write_tum(tmp_path / "other.tum", est)
    base = ["ape", str(tmp_path / "gt.tum"), str(run / "trajectory.tum"), str(tmp_path / "other.tum"), "--json"]
    assert main([*base, "--label", "LIO (ours)", "--label", "odom", "--plot", str(tmp_path / "p.svg")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in doc["results"]] == ["LIO (ours)", "odom"]
    svg = (tmp_path / "p.svg").read_text(encoding="utf-8")
    assert "LIO (ours)" in svg
    assert "odom" in svg
    assert main(base) == 0  # default: the slam run's folder, else the file name
    assert [r["name"] for r in json.loads(capsys.readouterr().out)["results"]] == [run.name, "other"]
    assert main([*base, "--label", "one"]) == 2
    assert "--label given 1 time(s) for 2 estimate(s)" in capsys.readouterr().err


def test_the_fast_ape_path_stays_fast_with_and_without_label() -> None:
    from mrnc_eval import cli
    from mrnc_eval.cli_fast import fast_command

    commands = {"ape": cli.ape, "rpe": cli.rpe}
    plain = fast_command(["ape", "ref.tum", "est.tum"], commands)
    assert plain is not None
    assert plain[1].get("label") is None  # not given: the function default
    labelled = fast_command(["ape", "ref.tum", "a.tum", "b.tum", "--label", "A", "--label", "B"], commands)
    assert labelled is not None
    assert labelled[1]["label"] == ["A", "B"]  # repeatable: in order, as typer gives it
