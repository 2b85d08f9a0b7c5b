"""The compiled-kernel decorator of the control package, with a numba cache that stays consistent
with the package's sources.

numba invalidates a cached function only when its own file changes; the closed loop inlines
kernels from other modules (raid.py, plant.py, ...), so editing one of those would silently
reuse a stale compiled loop. The kernels' cache entries are therefore stamped with a hash of
every control source: numba itself then treats an entry compiled from other sources as stale
and recompiles (nothing is deleted, nothing happens on import).
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numpy as np
from numba import njit
from numba.core import caching
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
F = TypeVar("F", bound=Callable[..., Any])


def pack_slots(values: dict[int, float]) -> list[float]:
    """A parameter vector from {slot: value} (slots 0..n-1, each once): kernels read it by slot name."""
    if sorted(values) != list(range(len(values))):
        raise ValueError(f"slots must be 0..{len(values) - 1}, each once: {sorted(values)}")
    return [float(values[k]) for k in range(len(values))]


_HERE = Path(__file__).parent


@functools.cache
def package_digest() -> str:
    """sha256 over the names and contents of the package's sources (once per process)."""
    digest = hashlib.sha256()
    for src in sorted(_HERE.glob("*.py")):
        digest.update(src.name.encode())
        digest.update(src.read_bytes())
    return digest.hexdigest()


class _PackageStamp:
    """Locator mixin: the source stamp is the file's own and the package digest."""

    def get_source_stamp(self) -> Any:
        return (super().get_source_stamp(), package_digest())  # type: ignore[misc]


class _InTree(_PackageStamp, caching.InTreeCacheLocator):
    pass


class _UserProvided(_PackageStamp, caching.UserProvidedCacheLocator):
    pass


class _UserWide(_PackageStamp, caching.UserWideCacheLocator):
    pass


class _PackageCacheImpl(caching.CompileResultCacheImpl):
    _locator_classes = [_UserProvided, _InTree, _UserWide]  # noqa: RUF012 (numba reads this class attribute)


class _PackageCache(caching.FunctionCache):
    _impl_class = _PackageCacheImpl


def kernel(fn: F) -> F:
    """numba.njit with an on-disk cache stamped by the package digest, keeping the function's
    signature for the type checker (numba ships no type information)."""
    dispatcher = njit(fn)
    dispatcher._cache = _PackageCache(dispatcher.py_func)  # type: ignore[no-untyped-call]
    return cast(F, dispatcher)
