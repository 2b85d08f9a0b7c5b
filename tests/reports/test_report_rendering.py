"""Reports of real pipeline results: opened in headless Chromium, PDF rendered to PNG."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mrnc_eval.cli import main

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PROBE = """
<script>
window.addEventListener('load', () => {
  const svgs = [...document.querySelectorAll('figure svg')];
  const sizes = svgs.map(s => { const b = s.getBoundingClientRect(); return b.width > 50 && b.height > 50; });
  const drawn = svgs.map(s => s.querySelectorAll('path, use, line, polyline').length > 10);
  document.body.setAttribute('data-figures', svgs.length);
  document.body.setAttribute('data-rendered', sizes.filter(x => x).length);
  document.body.setAttribute('data-drawn', drawn.filter(x => x).length);
});
</script>
"""


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("Chromium is not installed (scripts/setup.sh --test installs Debian's chromium)")


@pytest.fixture(scope="module")
def night(tiny_logs: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reports")
    rc = main(["nightly", str(tiny_logs), "--out", str(out), "--jobs", "1", "--date", "2026-11-20"])
    assert rc in (0, 1)  # gates may fail on these short logs; nothing may crash
    return out / "2026-11-20"


def test_report_opens_in_chromium_with_all_figures(night: Path, tmp_path: Path) -> None:
    chromium = _chromium()
    report = night / "logs" / "a" / "report.html"
    page = tmp_path / "probe.html"
    page.write_text(report.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    proc = subprocess.run([chromium, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
                           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--dump-dom",
                           page.as_uri()], capture_output=True, text=True, timeout=120)
    body = re.search(r"<body[^>]*>", proc.stdout)
    assert body, proc.stderr[-2000:]
    attrs = dict(re.findall(r'data-(\w+)="(\d+)"', body.group(0)))
    assert int(attrs["figures"]) >= 5
    assert attrs["rendered"] == attrs["figures"] and attrs["drawn"] == attrs["figures"]
    console = [ln for ln in proc.stderr.splitlines() if "CONSOLE" in ln]
    assert not console, console


def test_pdf_pages_are_not_blank(night: Path, tmp_path: Path) -> None:
    if not shutil.which("pdftoppm"):
        pytest.skip("pdftoppm is not installed (poppler-utils; scripts/setup.sh --test installs it)")
    from PIL import Image

    pdf = night / "logs" / "a" / "report.pdf"
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    pages = int(re.search(r"Pages:\s+(\d+)", info).group(1))
    subprocess.run(["pdftoppm", "-r", "40", "-png", str(pdf), str(tmp_path / "p")], check=True)
    pngs = sorted(tmp_path.glob("p-*.png"))
    assert len(pngs) == pages >= 2
    for png in pngs:
        arr = np.asarray(Image.open(png).convert("L"))
        assert (arr < 200).mean() > 0.005, png.name  # some ink on every page


def test_index_and_trends_link_reports(night: Path) -> None:
    index = (night / "index.html").read_text(encoding="utf-8")
    for log_id in ("a", "b", "c"):
        assert f'href="logs/{log_id}/report.html"' in index
    assert (night.parent / "trends.html").exists()
    assert (night / "logs" / "a" / "slam" / "trajectory.tum").exists()
