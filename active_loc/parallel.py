"""When this process may launch numba's parallel (``prange``) kernels, and on how many threads.

numba's GNU OpenMP threading layer kills a child process forked after its parent launched a
parallel kernel as soon as the child launches one ("fork() called from a process already using
GNU OpenMP"). Every hot loop that runs in parallel therefore has a serial twin compiled from
the same body, and :func:`use_parallel` says which one to call: the parallel one, unless this
process is such a child (a fork-started subprocess vector env, say), or the calling thread asked
for one thread. Both twins compute the same numbers (loops over particles or cells write their
own outputs; reductions sum fixed blocks in a fixed order), so the choice never changes a result.
"""

from __future__ import annotations

import contextlib
import os
import threading
import types
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba


class _PrangeSafety:
    launched = False  # this process has launched a parallel kernel
    forbidden = False  # a child forked after that: launching one would kill the process

    @classmethod
    def after_fork_in_child(cls) -> None:
        cls.forbidden = cls.launched


if hasattr(os, "register_at_fork"):  # POSIX; other platforms have no fork
    os.register_at_fork(after_in_child=_PrangeSafety.after_fork_in_child)

_local = threading.local()


def use_parallel() -> bool:
    """Whether the calling thread should call a kernel's parallel twin now (and, if so, that
    it is about to: a fork after this point makes the child use the serial twins)."""
    if _PrangeSafety.forbidden or getattr(_local, "threads", 0) == 1:
        return False
    _PrangeSafety.launched = True
    threads = getattr(_local, "threads", 0)
    if threads:
        numba.set_num_threads(threads)  # numba's setting is per calling thread
    return True


def set_thread_count(threads: int) -> None:
    """Run the calling thread's parallel kernels on ``threads`` numba threads (1: the serial
    twins; 0: numba's default). Worker threads that already share the cores set 1."""
    _local.threads = int(threads)


@contextlib.contextmanager
def thread_count(threads: int | None) -> Iterator[None]:
    """:func:`set_thread_count` for the calls inside the ``with`` block, then the calling
    thread's setting as it was; None leaves the setting alone."""
    if threads is None:
        yield
        return
    before = getattr(_local, "threads", 0)
    _local.threads = int(threads)
    try:
        yield
    finally:
        _local.threads = before
        if threads > 1 and _PrangeSafety.launched and not _PrangeSafety.forbidden:
            # numba's own setting is per thread too: put back what use_parallel will not
            numba.set_num_threads(before or numba.config.NUMBA_NUM_THREADS)


def prange_forbidden() -> bool:
    """Whether this process is a child forked after its parent launched a parallel kernel."""
    return _PrangeSafety.forbidden


def note_parallel_launch() -> None:
    """Record that this process launches a parallel kernel."""
    _PrangeSafety.launched = True


def parallel_twin(kernel: Any) -> Any:
    """The parallel twin of a serial ``numba.njit`` kernel whose loops over particles or cells
    are ``numba.prange`` loops that write only their own outputs (no reductions across them):
    the same body compiled with ``parallel=True``, under a name of its own so that numba's
    on-disk cache keeps the two apart."""
    fn = kernel.py_func
    twin = types.FunctionType(fn.__code__, fn.__globals__, f"{fn.__name__}_parallel",
                              fn.__defaults__, fn.__closure__)
    twin.__qualname__ = f"{fn.__qualname__}_parallel"
    twin.__module__ = fn.__module__
    twin.__doc__ = fn.__doc__
    return numba.njit(cache=True, nogil=True, parallel=True)(twin)


def pick(serial: Any, parallel: Any) -> Any:
    """``parallel`` when :func:`use_parallel` allows it, else ``serial``."""
    return parallel if use_parallel() else serial


class WorkerThreads:
    """Worker threads that run the tasks of a step, one member each (started when first
    needed)."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool: ThreadPoolExecutor | None = None

    def run_tasks(self, fn: Any, tasks: list[Any]) -> None:
        """``fn(task)`` for every task, the threads each taking the next one left in the list
        as they finish one (put the longest first: the threads then end together); re-raises
        the first error (a failing step, say) after all have finished."""
        if self._pool is None:
            # the workers already share the cores: each runs the kernels' serial twins
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="active_loc",
                                            initializer=set_thread_count, initargs=(1,))
        queue = iter(tasks)  # next() on a list iterator is atomic under the GIL

        def drain() -> None:
            for task in queue:
                fn(task)

        threads = min(self.workers, len(tasks))
        for future in [self._pool.submit(drain) for _ in range(threads)]:
            future.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __getstate__(self) -> dict[str, Any]:
        return {"workers": self.workers, "_pool": None}  # threads do not pickle
