"""The compiled-kernel decorator of the control package, and keeping numba's on-disk cache of
those kernels consistent with their sources.

numba invalidates a cached function only when its own file changes; the closed loop inlines
kernels from other modules (raid.py, plant.py, ...), so editing one of those would silently
reuse a stale compiled loop. On import we hash every control source and drop the package's
cache files when the hash differs from the one recorded beside them.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
F = TypeVar("F", bound=Callable[..., Any])


def pack_slots(values: dict[int, float]) -> list[float]:
    """A parameter vector from {slot: value} (slots 0..n-1, each once): kernels read it by slot name."""
    if sorted(values) != list(range(len(values))):
        raise ValueError(f"slots must be 0..{len(values) - 1}, each once: {sorted(values)}")
    return [float(values[k]) for k in range(len(values))]


def kernel(fn: F) -> F:
    """numba.njit(cache=True) that keeps the function's signature for the type checker (numba
    ships no type information, so a bare @njit would make every kernel untyped). numba is imported
    here, not with the package: the configuration (control.config) loads without it, and a kernel
    module without numba stops with MissingExtra naming the extra."""
    try:
        from numba import njit
    except ImportError:
        from mrnc_eval.errors import MissingExtra

        raise MissingExtra("the control chain needs numba: pip install 'mrnc-eval[control]' "
                           "(or 'mrnc-eval[slam]', which includes it)") from None
    return cast(F, njit(cache=True)(fn))


_HERE = Path(__file__).parent
_STAMP = "control-sources.sha256"


def ensure_consistent_cache(cache_dir: Path | None = None) -> bool:
    """Remove stale *.nbi/*.nbc of this package. Returns True when files were removed."""
    cache_dir = cache_dir or _HERE / "__pycache__"
    digest = hashlib.sha256()
    for src in sorted(_HERE.glob("*.py")):
        digest.update(src.name.encode())
        digest.update(src.read_bytes())
    stamp = cache_dir / _STAMP
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except OSError:
        pass
    removed = False
    try:
        cache_dir.mkdir(exist_ok=True)
        for f in list(cache_dir.glob("*.nbi")) + list(cache_dir.glob("*.nbc")):
            f.unlink(missing_ok=True)
            removed = True
        stamp.write_text(digest.hexdigest())
    except OSError:  # read-only install: numba falls back to its own cache locator or compiles
        pass
    return removed
