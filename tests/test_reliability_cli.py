"""Issue 15's eighteen reproductions, each through the CLI (see tests/reliability_cases.py):
the exit code and the harm the issue was about (a deleted file, a number that passed, a
traceback, a forged line) are asserted per case."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.reliability_cases import CASES, Workspace, make_sim_log


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_sim_log(tmp_path_factory.mktemp("reliability_sim"))


@pytest.mark.parametrize("case", CASES, ids=[c.__name__.removeprefix("case_") for c in CASES])
def test_reproduction(case, sim_log: Path, tmp_path: Path) -> None:
    outcome = case(Workspace(tmp_path, sim_log))
    assert outcome.code == outcome.expected, f"{outcome.case}: exit {outcome.code}, {outcome.detail}"
    assert outcome.harm_avoided, f"{outcome.case}: {outcome.detail}"
