"""Read ahead in a background thread, so decompressing and decoding the next sweeps overlaps
with processing this one (zstd/lz4 and numpy release the GIL for most of that work)."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import Generic, TypeVar, cast

T = TypeVar("T")
_END = object()


class Prefetched(Generic[T]):
    """`with Prefetched(items, depth) as it: for x in it: ...` iterates `items` in a worker thread
    at most `depth` items ahead. Errors raised by `items` are raised in the consumer, in order.
    Leaving the block stops the worker and waits for it, so the source (an open log) can be
    closed safely afterwards, also when the consumer stopped early."""

    def __init__(self, items: Iterable[T], depth: int = 4) -> None:
        if depth < 1:
            raise ValueError("depth must be >= 1")
        self._items = items
        self._queue: queue.Queue[object] = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._work, name="prefetch", daemon=True)

    def _put(self, item: object) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _work(self) -> None:
        it = iter(self._items)
        try:
            for item in it:
                if not self._put(item):
                    return
        except BaseException as err:  # noqa: BLE001 - handed to the consumer's thread, which raises it
            self._put((_END, err))
            return
        finally:
            close = getattr(it, "close", None)
            if close is not None:  # a generator over an open log: finish it in this thread
                close()
        self._put((_END, None))

    def __enter__(self) -> Iterator[T]:
        self._thread.start()
        return self._iterate()

    def _iterate(self) -> Iterator[T]:
        while True:
            item = self._queue.get()
            if isinstance(item, tuple) and len(item) == 2 and item[0] is _END:
                if item[1] is not None:
                    raise item[1]
                return
            yield cast(T, item)  # anything but the end marker is an item of the source

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
