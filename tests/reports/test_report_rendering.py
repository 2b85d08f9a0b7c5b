"""Reports of real pipeline results (simulated logs through info, SLAM, control replay): opened
in headless Chromium, PDF rendered to PNG, tables exported, re-rendered by the report verb."""

from __future__ import annotations

import builtins
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main
from mrnc_eval.outputs import MANIFEST

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PROBE = """
<script>
window.addEventListener('load', () => {
  const svgs = [...document.querySelectorAll('figure svg')];
  const sized = svgs.filter(s => { const b = s.getBoundingClientRect(); return b.width > 50 && b.height > 50; });
  const drawn = svgs.filter(s => s.querySelectorAll('path, use, line, polyline').length > 10);
  const broken = [...document.querySelectorAll('img')].filter(i => !i.complete || i.naturalWidth === 0);
  document.body.setAttribute('data-figures', svgs.length);
  document.body.setAttribute('data-sized', sized.length);
  document.body.setAttribute('data-drawn', drawn.length);
  document.body.setAttribute('data-broken', broken.length);
  document.body.setAttribute('data-probed', 1);
});
</script>
"""


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("Chromium is not installed (scripts/setup.sh --test installs Debian's chromium)")


def open_in_chromium(page: Path, tmp_path: Path) -> tuple[dict[str, int], list[str]]:
    """Load a copy of `page` (same folder, so relative links resolve) with a probe script; return
    the probe's counts and the console lines Chromium logged."""
    probe = page.with_name(f".probe-{page.name}")
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    try:
        proc = subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
                               "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--dump-dom",
                               probe.as_uri()], capture_output=True, text=True, timeout=120)
    finally:
        probe.unlink()
    body = re.search(r"<body[^>]*>", proc.stdout)
    assert body, proc.stderr[-2000:]
    assert "data-probed" in body.group(0), proc.stderr[-2000:]
    counts = {k: int(v) for k, v in re.findall(r'data-(\w+)="(\d+)"', body.group(0))}
    return counts, [ln for ln in proc.stderr.splitlines() if "CONSOLE" in ln or "Uncaught" in ln]


@pytest.fixture(scope="module")
def night(tiny_logs: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reports")
    rc = main(["nightly", str(tiny_logs), "--out", str(out), "--jobs", "1", "--date", "2026-11-20"])
    assert rc in (0, 1)  # gates may fail on these short logs; nothing may fail to run
    return out / "2026-11-20"


@pytest.mark.parametrize("log_id", ["a", "nested_b"])
def test_report_opens_in_chromium_with_every_figure_drawn(night: Path, tmp_path: Path, log_id: str) -> None:
    report = night / "logs" / log_id / "report.html"
    counts, console = open_in_chromium(report, tmp_path)
    # SLAM: trajectory, APE over time, timing; control replay: tracking, effort, path
    assert counts["figures"] == 6
    assert counts["sized"] == counts["drawn"] == counts["figures"]
    assert counts["broken"] == 0
    assert not console, console
    html = report.read_text(encoding="utf-8")
    assert not re.search(r'<img|<link|<script|src=|href="(?!#|data:)[a-z]+:|url\((?!#)', html)  # self-contained
    for heading in ("Log health", "SLAM (lio)", "Control", "Configuration"):
        assert f"<h2>{heading}</h2>" in html
    for card in ("APE RMSE (lio)", "Funnel violations", "Saturation ratio", "Safety stops"):
        assert f'<div class="l">{card}</div>' in html


def test_index_and_trends_open_in_chromium_and_link_every_report(night: Path, tmp_path: Path) -> None:
    index = night / "index.html"
    counts, console = open_in_chromium(index, tmp_path)
    assert not console, console
    text = index.read_text(encoding="utf-8")
    for log_id in ("a", "nested_b"):
        assert f'href="logs/{log_id}/report.html"' in text
        assert f'href="logs/{log_id}/report.pdf"' in text
        assert (night / "logs" / log_id / "report.pdf").exists()
    counts, console = open_in_chromium(night.parent / "trends.html", tmp_path)
    assert not console, console
    assert counts["figures"] >= 3
    assert counts["sized"] == counts["figures"]


def test_pdf_pages_are_not_blank(night: Path, tmp_path: Path) -> None:
    if not shutil.which("pdftoppm"):
        pytest.skip("pdftoppm is not installed (poppler-utils; scripts/setup.sh --test installs it)")
    from PIL import Image

    pdf = night / "logs" / "a" / "report.pdf"
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    pages = int(re.search(r"Pages:\s+(\d+)", info).group(1))
    assert re.search(r"Producer:\s+WeasyPrint", info)
    subprocess.run(["pdftoppm", "-r", "40", "-png", str(pdf), str(tmp_path / "p")], check=True)
    pngs = sorted(tmp_path.glob("p-*.png"))
    assert len(pngs) == pages >= 4  # health, SLAM, control, configuration
    assert pages <= 6  # SLAM + control without --appendix-config: the configuration is a list of changed keys
    for png in pngs:
        arr = np.asarray(Image.open(png).convert("L"))
        body = arr[: int(arr.shape[0] * 0.94)]  # above the bottom margin's page number ("11 / 11")
        # some ink on every page: a last page with three lines of the configuration listing has 0.2 %,
        # a blank one 0 (a fixed 0.5 % failed whenever the listing's last page came out short)
        assert (body < 200).mean() > 0.0005, png.name
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    for words in ("Log health", "SLAM key numbers", "Table II layout", "Configuration", "--appendix-config"):
        assert words in text
    assert "Appendix: effective configuration" not in text


def test_appendix_config_adds_the_full_configuration_on_request(night: Path, tmp_path: Path) -> None:
    """The full configuration only with report --appendix-config (the negative control of the page limit)."""
    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext is not installed (poppler-utils; scripts/setup.sh --test installs it)")
    log_dir = night / "logs" / "a"
    assert main(["report", str(log_dir), "--out", str(tmp_path / "full"), "--pdf", "--appendix-config"]) in (0, 1)
    pdf = tmp_path / "full" / "report.pdf"
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    assert "Appendix: effective configuration" in text
    assert "mapping_interval_s" in text  # a key only the full listing has (the defaults differ in nothing)
    full = int(re.search(r"Pages:\s+(\d+)", subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True,
                                                             check=True).stdout).group(1))
    short = int(re.search(r"Pages:\s+(\d+)", subprocess.run(["pdfinfo", str(log_dir / "report.pdf")],
                                                              capture_output=True, text=True,
                                                              check=True).stdout).group(1))
    assert full > short


def test_tables_exported_and_report_verb_rerenders_without_recomputing(night: Path, tmp_path: Path) -> None:
    from mrnc_eval.results import read_result

    log_dir = night / "logs" / "a"
    slam = read_result(log_dir / "slam")
    csv = (log_dir / "slam_table1.csv").read_text(encoding="utf-8").splitlines()
    # the result's number to 0.1 mm (a metre column; float32 noise stays out, result.json keeps it all);
    # Table I takes the online trajectory by default (slam.table_trajectory)
    assert csv[1].split(",")[1] == repr(round(slam.metric("ape_online_rmse_m").value, 4))
    assert "\\begin{tabular}" in (log_dir / "control_table2.tex").read_text(encoding="utf-8")
    out = tmp_path / "again"
    assert main(["report", str(log_dir), "--out", str(out)]) == 0
    again = (out / "report.html").read_text(encoding="utf-8")
    first = (log_dir / "report.html").read_text(encoding="utf-8")
    strip = lambda s: re.sub(r"generated [^<]+|f\d+-", "", s)  # noqa: E731 - timestamp, figure id prefixes
    assert strip(again) == strip(first)
    assert main(["report", str(tmp_path / "missing")]) == 4


def test_pdf_without_weasyprint_is_an_error_naming_the_extra(tmp_path: Path, monkeypatch) -> None:
    """No placeholder PDF: `report --pdf` without a PDF engine exits 2 naming the pdf extra and writes
    nothing; without --pdf the same report is written."""
    from mrnc_eval.errors import MissingExtra
    from mrnc_eval.reports.render import write_pdf

    real_import = builtins.__import__

    def no_weasyprint(name, *args, **kwargs):
        if name == "weasyprint":
            raise OSError("cannot load library 'libpango-1.0-0'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_weasyprint)
    with pytest.raises(MissingExtra, match="Pango"):
        write_pdf("<html><body>x</body></html>", tmp_path / "r.pdf")
    assert [p.name for p in tmp_path.iterdir() if p.name != MANIFEST] == []  # nothing written


def test_simulated_control_report_has_table_two_and_a_funnel_only_for_raid(tmp_path: Path) -> None:
    assert main(["control", "--mode", "simulate", "--controllers", "raid,pid", "--out", str(tmp_path / "res")]) == 0
    (result_dir,) = [p.parent for p in (tmp_path / "res").rglob("result.json")]
    assert main(["report", str(result_dir), "--out", str(tmp_path / "rep")]) == 0
    html = (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")
    captions = re.findall(r"<figcaption>([^<]*)</figcaption>", html)
    # tracking, effort, feedback share (and phi-hat for RAID), path per controller; one Bode plot of the laws
    assert len(captions) == 9
    assert sum("Open loop" in c for c in captions) == 1
    assert sum("phi-hat" in c for c in captions) == 1
    assert [c for c in captions if "funnel" in c] == ["RAID: wheel-speed reference vs measured, funnel band "
                                                      "reference ± o(t)"]
    assert "Table II" in html
    assert (tmp_path / "rep" / "control_table2.tex").exists()
    counts, console = open_in_chromium(tmp_path / "rep" / "report.html", tmp_path)
    assert counts["figures"] == counts["sized"] == counts["drawn"] == 9
    assert not console
