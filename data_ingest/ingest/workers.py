"""Ingesting logs in worker processes that never outlive the run.

:func:`in_workers` runs jobs in a fork pool whose workers ignore Ctrl-C (the parent decides)
and die with their parent (:mod:`lanelab.child_processes`). On Ctrl-C the parent gets the
results already finished, then the workers are killed; a ``kill -9`` of the parent kills them too.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Callable, Iterator, Sequence, TypeVar

from lanelab.child_processes import init_worker, kill_pool

T = TypeVar("T")
_counter = None  # bytes read, shared with the worker processes


def _init_worker(counter: Any, parent_pid: int) -> None:
    global _counter
    _counter = counter
    init_worker(parent_pid)


def _count_bytes(n: int) -> None:
    with _counter.get_lock():
        _counter.value += n


def _call(function: Callable[..., T], args: tuple) -> T:
    return function(*args, _count_bytes)


def in_workers(function: Callable[..., T], jobs: Sequence[tuple], workers: int,
               progress: Callable[[int], None]) -> Iterator[T]:
    """``function(*job, count_bytes)`` for each job in ``workers`` processes; the results as they finish.

    ``function`` must be picklable (module level); ``progress(n)`` gets the bytes counted by
    all workers so far. On KeyboardInterrupt, the results already finished are yielded,
    then the interrupt goes on; whatever else ends the iteration early kills the workers too.
    """
    ctx = mp.get_context("fork")
    counter = ctx.Value("q", 0)
    pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker, initargs=(counter, os.getpid()))
    try:
        pending = {pool.submit(_call, function, job) for job in jobs}
        while pending:
            try:
                done, pending = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
            except KeyboardInterrupt:
                yield from (future.result() for future in pending if _finished(future))
                raise
            progress(counter.value)
            yield from (future.result() for future in done)
    except BaseException:  # Ctrl-C, a broken pool, or the caller stopped iterating (GeneratorExit)
        kill_pool(pool)
        raise
    pool.shutdown()


def _finished(future: Future) -> bool:
    return future.done() and not future.cancelled() and future.exception() is None

