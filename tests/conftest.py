"""Shared fixtures. Tests write small logs with the project's writers; the real Ouster
recording lives in ../shared/data (beside the repository)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.needs import missing

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
REAL_OUSTER = SHARED_DATA / "ouster-os1-128-real-3scans" / "ouster_real_ros2_mcap_zstd.mcap"

# evo writes ~/.evo/settings.json on first import: keep it out of the user's home.
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session")
def real_ouster_mcap() -> Path:
    if not REAL_OUSTER.exists():
        missing(f"the real Ouster recording is missing: expected {REAL_OUSTER} (../shared/data beside the repository)")
    return REAL_OUSTER


@pytest.fixture(autouse=True, scope="session")
def _isolated_home(tmp_path_factory: pytest.TempPathFactory) -> None:
    home = tmp_path_factory.mktemp("home")
    os.environ["HOME"] = str(home)
