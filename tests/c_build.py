"""Build one of the package's C extensions from its source under test, the way setup.py does but
into a test folder, and import it under its package name; a missing compiler or Python.h is
`missing` (a failure in CI, a skip elsewhere)."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sysconfig
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from tests.needs import missing


def build_extension(source: Path, module: str, folder: Path, flags: Sequence[str] = ("-O3",)) -> ModuleType:
    """Compile `source` with `flags` into `folder` and import it as `module` (e.g. mrnc_eval.io._cloud)."""
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    include = sysconfig.get_paths()["include"]
    if shutil.which(cc) is None or not (Path(include) / "Python.h").exists():
        missing(f"cannot build {source.name}: no C compiler ({cc}) or no Python.h in {include}")
    out = folder / (module.rsplit(".", 1)[-1] + sysconfig.get_config_var("EXT_SUFFIX"))
    subprocess.run([cc, *flags, "-shared", "-fPIC", f"-I{include}", str(source), "-o", str(out)], check=True)
    spec = importlib.util.spec_from_file_location(module, out)
    assert spec is not None
    assert spec.loader is not None
    loaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loaded)
    return loaded
