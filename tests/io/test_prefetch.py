"""The read-ahead thread: same items in order, source errors raised in the consumer, and an
early stop that finishes the source in the worker before the block is left."""

from __future__ import annotations

import threading

import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.io.prefetch import Prefetched


def test_items_arrive_in_order_and_the_worker_runs_ahead() -> None:
    produced: list[int] = []

    ran_ahead = threading.Event()

    def source():
        for i in range(50):
            produced.append(i)
            if len(produced) == 4:  # the worker fills the queue (3) and holds one more
                ran_ahead.set()
            yield i

    with Prefetched(source(), depth=3) as it:
        first = next(it)
        # Bounded wait: a worker that does not run ahead fails here in 5 s, not at the suite's timeout.
        assert ran_ahead.wait(timeout=5.0), f"the worker produced {len(produced)} item(s) ahead, expected 4"
        rest = list(it)
    assert [first, *rest] == list(range(50))


def test_a_source_error_is_raised_in_the_consumer_after_the_good_items() -> None:
    def source():
        yield 1
        yield 2
        raise InputError("log.mcap", "corrupted chunk", topic="/ouster/points")

    got = []
    with pytest.raises(InputError, match="corrupted chunk"), Prefetched(source()) as it:  # noqa: PT012 - consume
        for x in it:
            got.append(x)
    assert got == [1, 2]


def test_stopping_early_closes_the_source_in_the_worker() -> None:
    closed = threading.Event()

    def source():
        try:
            i = 0
            while True:
                yield i
                i += 1
        finally:
            closed.set()

    with Prefetched(source(), depth=2) as it:
        assert next(it) == 0
    assert closed.is_set()  # done before the block returned, so the log can be closed now
