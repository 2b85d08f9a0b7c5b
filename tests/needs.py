"""What a test needs from outside the project (evo, kiss-icp, a C compiler, the real recording in
../shared/data). Tests of the central claims must not pass silently without it: with CI=true a
missing need fails the test; elsewhere the test skips, with the same message."""

from __future__ import annotations

import importlib
import os
from types import ModuleType
from typing import NoReturn

import pytest


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() in ("1", "true", "yes")


def missing(reason: str) -> NoReturn:
    """Fail (CI) or skip (elsewhere) the current test, saying what is missing."""
    if in_ci():
        pytest.fail(reason, pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def need_module(name: str, reason: str) -> ModuleType:
    """The module `name`, or fail/skip with `reason` when it cannot be imported."""
    try:
        return importlib.import_module(name)
    except ImportError:
        missing(reason)
