"""Optional parts of the installation: which verb needs which extra, checked before any work.

`pip install mrnc-eval` gives info, ape, rpe, table, report, compare and export; the SLAM stack
(gtsam, numba, pykdtree) is `mrnc-eval[slam]`, the control chain's compiled kernels
`[control]`, the simulator `[sim]`, PDF reports `[pdf]` (scripts/setup.sh installs all). A verb
whose extra is missing stops with MissingExtra naming it, instead of an ImportError deep inside.
"""

from __future__ import annotations

import importlib.util

from mrnc_eval.errors import MissingExtra

# extra -> the modules it provides (import names)
EXTRAS: dict[str, tuple[str, ...]] = {
    "slam": ("gtsam", "numba", "pykdtree"),  # no open3d: slam/icp.py, io/ply.py, io/pcd.py
    "control": ("numba",),
    "sim": ("open3d", "numba"),
    "pdf": ("weasyprint",),
    "dask": ("dask", "distributed"),
    "kiss-icp": ("kiss_icp",),
}


def missing_modules(extra: str) -> list[str]:
    """The modules of `extra` that cannot be imported here (found, not imported: cheap)."""
    out = []
    for name in EXTRAS[extra]:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a blocked or half-installed package
            found = False
        if not found:
            out.append(name)
    return out


def require_extra(extra: str, what: str) -> None:
    """MissingExtra when `extra` is not installed: `what` (e.g. "mrnc-eval slam") needs it."""
    missing = missing_modules(extra)
    if missing:
        raise MissingExtra(f"{what} needs the {extra} extra (missing: {', '.join(missing)}): "
                           f"pip install 'mrnc-eval[{extra}]' (or 'mrnc-eval[all]'; scripts/setup.sh installs all)")
