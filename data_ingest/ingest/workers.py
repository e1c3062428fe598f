"""Ingesting logs in worker processes that never outlive the run.

:func:`in_workers` runs jobs in a fork pool whose workers ignore Ctrl-C (the parent decides)
and die with their parent: Linux's ``prctl(PR_SET_PDEATHSIG, SIGKILL)``, elsewhere a thread
that watches the parent's pid. On Ctrl-C the parent gets the results already finished, then
the workers are killed; a ``kill -9`` of the parent kills them too.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Callable, Iterator, Sequence, TypeVar

PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCH_S = 0.5  # how often the fallback thread looks for its parent

T = TypeVar("T")
_counter = None  # bytes read, shared with the worker processes


def die_with_parent(parent_pid: int) -> None:
    """Make this process exit when the process ``parent_pid`` (its parent) does."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):  # no prctl: not Linux
        armed = False
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(WATCH_S)
    os._exit(1)


def _init_worker(counter: Any, parent_pid: int) -> None:
    global _counter
    _counter = counter
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


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
        _kill(pool)
        raise
    pool.shutdown()


def _finished(future: Future) -> bool:
    return future.done() and not future.cancelled() and future.exception() is None


def _kill(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's workers, idle or busy, and shut it down without waiting for their jobs."""
    for process in list((pool._processes or {}).values()):
        process.kill()
    pool.shutdown(wait=True, cancel_futures=True)
