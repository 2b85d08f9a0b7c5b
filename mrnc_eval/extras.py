"""Optional parts of the installation: which verb needs which extra, checked before any work.

`pip install mrnc-eval` gives info, ape, rpe, table, report, compare and export; the SLAM stack
(gtsam, pykdtree; its per-sweep kernels are C, below) is `mrnc-eval[slam]`, the control chain's compiled kernels
`[control]`, the simulator `[sim]`, PDF reports `[pdf]` (scripts/setup.sh installs all). A verb
whose extra is missing stops with MissingExtra naming it, instead of an ImportError deep inside.
The SLAM's loops are also this package's own C extensions (setup.py): built at install when a C
compiler and Python's headers are there, optional there so that the base install never fails, and
checked here the same way, with a message that says how to build them.
"""

from __future__ import annotations

import importlib.util

from mrnc_eval.errors import MissingExtra

# extra -> the modules it provides (import names)
EXTRAS: dict[str, tuple[str, ...]] = {
    "slam": ("gtsam", "pykdtree"),  # no open3d: slam/icp.py, io/ply.py, io/pcd.py
    "control": ("numba",),
    "sim": ("open3d", "numba"),
    "pdf": ("weasyprint",),
    "dask": ("dask", "distributed"),
    "kiss-icp": ("kiss_icp",),
}
# extra -> this package's compiled extensions its verbs need (setup.py's Extension lines)
BUILT: dict[str, tuple[str, ...]] = {
    "slam": ("mrnc_eval.slam._prep_kernels",  # range image, deskew, features, gyro track (slam/_prep_kernels.c)
             "mrnc_eval.slam._match_kernels"),  # scan-to-map's map search, fits and rows (slam/_match_kernels.c)
}


def missing_modules(extra: str) -> list[str]:
    """The modules of `extra` that cannot be imported here (found, not imported: cheap)."""
    return _not_found(EXTRAS[extra])


def missing_builds(extra: str) -> list[str]:
    """The compiled extensions `extra`'s verbs need that were not built at install (found, not imported)."""
    return _not_found(BUILT.get(extra, ()))


def _not_found(names: tuple[str, ...]) -> list[str]:
    out = []
    for name in names:
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
    unbuilt = missing_builds(extra)
    if unbuilt:
        raise MissingExtra(f"{what} needs its compiled kernels ({', '.join(unbuilt)}), which were not built when "
                           "mrnc-eval was installed (no C compiler or no Python headers then): install gcc and the "
                           "Python headers (Debian: apt-get install gcc python3-dev; scripts/setup.sh does), then "
                           "reinstall mrnc-eval (pip install --force-reinstall --no-deps --no-cache-dir -e . in a "
                           "checkout, or bash scripts/setup.sh)")


def read_ahead(extra: str) -> int:
    """Ask the kernel to read `extra`'s compiled libraries (the packages' .so files and the
    libraries their wheels vendor in `<name>.libs/`) into the page cache now, in the background:
    from a cold cache (after a reboot or an install) the loader otherwise reads them page by page
    when the module is imported (gtsam: ~60 MB, imported last in a SLAM run). Only advice, found
    not imported; returns how many files were advised (0 where the platform has no fadvise)."""
    import os
    from pathlib import Path

    if not hasattr(os, "posix_fadvise"):
        return 0
    files: list[Path] = []
    for name in (*EXTRAS[extra], *BUILT.get(extra, ())):
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            continue
        if spec is None:
            continue
        for folder in spec.submodule_search_locations or ():  # a package: its extensions and vendored libraries
            files += [*Path(folder).glob("*.so*"), *Path(folder).with_name(f"{Path(folder).name}.libs").glob("*.so*")]
        if spec.origin and ".so" in Path(spec.origin).name:
            files.append(Path(spec.origin))
    advised = 0
    for path in files:
        try:
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            continue
        try:
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_WILLNEED)
            advised += 1
        except OSError:
            pass
        finally:
            os.close(fd)
    return advised
