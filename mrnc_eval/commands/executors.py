"""Where the logs of a night run, behind one interface: `executor.run(jobs)` yields one summary
per job as they finish (order not guaranteed).

- InProcess (--jobs 1): simplest, for debugging; a native crash ends the night.
- LocalPool (--jobs N): spawned processes, one task per process (max_tasks_per_child=1), so
  native state never leaks from one log to the next. A native crash breaks a
  ProcessPoolExecutor for every job in flight; those jobs are re-run one at a time in a fresh
  pool, so the crash is attributed to the log that caused it and its neighbours still finish.
- Dask (--scheduler tcp://HOST:PORT): the same job function on a distributed cluster; a worker
  that dies is restarted by its nanny and the scheduler retries or reports the task. Workers
  must see LOG_DIR and REPORT_ROOT at the same paths (a shared file system) and have
  mrnc-eval installed; the history is written by this process only.
"""

from __future__ import annotations

import multiprocessing
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Protocol

from mrnc_eval.commands.log_job import LogJob, LogSummary, failed_summary, process_log
from mrnc_eval.errors import UsageError

CRASHED = "worker process died while processing this log (native crash, out of memory or killed)"


class Executor(Protocol):
    def run(self, jobs: Iterable[LogJob]) -> Iterator[LogSummary]: ...


class InProcess:
    def run(self, jobs: Iterable[LogJob]) -> Iterator[LogSummary]:
        for job in jobs:
            yield process_log(job)


class LocalPool:
    def __init__(self, workers: int) -> None:
        self.workers = max(1, workers)

    def _pool(self, workers: int) -> ProcessPoolExecutor:
        import logging

        from mrnc_eval.text import install_log_format

        # a spawned worker starts without our log handler: give it the same escaping formatter
        return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   max_tasks_per_child=1, initializer=install_log_format,
                                   initargs=(logging.getLogger("mrnc_eval").getEffectiveLevel(), None))

    def run(self, jobs: Iterable[LogJob]) -> Iterator[LogSummary]:
        queue = deque(jobs)
        while queue:
            suspects: list[LogJob] = []
            yield from self._until_broken(queue, suspects)
            for job in suspects:  # alone in a fresh pool: a crash now is this log's own
                yield from self._alone(job)

    def _until_broken(self, queue: deque[LogJob], suspects: list[LogJob]) -> Iterator[LogSummary]:
        """Keep at most `workers` jobs in flight; stop submitting when the pool breaks and
        collect the jobs that were in flight then."""
        pool = self._pool(self.workers)
        inflight: dict[Future[LogSummary], LogJob] = {}
        try:
            while queue or inflight:
                while queue and len(inflight) < self.workers and not suspects:
                    job = queue.popleft()
                    inflight[pool.submit(process_log, job)] = job
                if not inflight:
                    break
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    job = inflight.pop(fut)
                    try:
                        yield fut.result()
                    except BrokenProcessPool:
                        suspects.append(job)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        if len(suspects) == 1:  # it was alone in flight or the only one hit: no need to re-run it
            yield failed_summary(suspects.pop(), CRASHED)

    def _alone(self, job: LogJob) -> Iterator[LogSummary]:
        pool = self._pool(1)
        try:
            yield pool.submit(process_log, job).result()
        except BrokenProcessPool:
            yield failed_summary(job, CRASHED)
        finally:
            pool.shutdown(wait=True)


class Dask:
    def __init__(self, address: str, timeout_s: float = 5.0) -> None:
        self.address = address
        self.timeout_s = timeout_s

    def run(self, jobs: Iterable[LogJob]) -> Iterator[LogSummary]:
        try:
            from distributed import Client
            from distributed import as_completed as dask_completed
        except ImportError as err:
            raise UsageError("--scheduler needs the dask extra: pip install 'mrnc-eval[dask]'") from err
        jobs = list(jobs)
        check_scheduler(self.address, self.timeout_s)
        try:
            client = Client(self.address, timeout=f"{self.timeout_s}s")
        except (OSError, TimeoutError) as err:
            raise UsageError(f"--scheduler {self.address}: no Dask scheduler answered within "
                             f"{self.timeout_s:g} s (nightly.scheduler_timeout_s): {err}") from err
        with client:
            futures = {client.submit(process_log, job, pure=False, key=f"mrnc-{k}-{job.log_id}"): job
                       for k, job in enumerate(jobs)}
            for fut in dask_completed(futures):
                try:
                    yield fut.result()
                except Exception as err:  # noqa: BLE001 - a worker's crash fails its log, not the night
                    yield failed_summary(futures[fut], f"{CRASHED}: {type(err).__name__}: {err}")


def check_scheduler(address: str, timeout_s: float) -> None:
    """One line naming the address when nothing listens there (Dask itself would wait, retry and
    end in a long traceback)."""
    import socket

    host, _, port = address.split("://", 1)[-1].rpartition(":")
    if not host or not port.isdigit():
        raise UsageError(f"--scheduler {address!r}: expected tcp://HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as err:
        raise UsageError(f"--scheduler {address}: nothing answers at {host}:{port} within {timeout_s:g} s "
                         f"({err.strerror or err}); is the Dask scheduler running?") from err


def make_executor(jobs: int, scheduler: str | None, timeout_s: float = 5.0) -> Executor:
    if jobs < 1:
        raise UsageError("--jobs must be >= 1")
    if scheduler:
        return Dask(scheduler, timeout_s)
    return InProcess() if jobs == 1 else LocalPool(jobs)
