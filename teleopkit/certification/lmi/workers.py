"""Independent LMI solves on the local cores.

Cells of a cover, and the vertex checks before a split, are independent problems: they are
solved by a pool of worker processes, one per core, started by a fork server that imports the
LMI modules once (forking the caller directly can deadlock on locks its threads hold). The
number of workers is ``os.cpu_count()`` unless the environment variable ``TELEOPKIT_WORKERS``
sets it (``1`` solves in this process). Results come back in the order of the tasks, so a cover
is the same whatever the number of workers.

Each worker gets its share of the cores (``os.cpu_count() // workers`` threads) for BLAS,
through :mod:`threadpoolctl`, and for Clarabel's linear algebra. Both default to every core, and
on the small dense blocks of these LMIs threads cost more than they give: with two workers
each running two BLAS and two solver threads on two cores, a level of cells took as long as
solving them one after the other in one process.

A worker starts by importing the caller's main module, as every non-fork start of
:mod:`multiprocessing` does, so a script must keep its work under
``if __name__ == "__main__":``. A script file without that guard would run again in each worker;
its solves run in the calling process instead, with a warning. From a notebook or the
interpreter prompt nothing is re-run.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

from certify.solve import set_solver_threads

__all__ = ["map_solves", "start_workers", "workers"]

_T = TypeVar("_T")
_POOL: dict[int, Executor] = {}


def workers() -> int:
    """Number of worker processes (``TELEOPKIT_WORKERS`` or the core count).

    Returns
    -------
    int
        At least 1.
    """
    text = os.environ.get("TELEOPKIT_WORKERS", "")
    try:
        count = int(text) if text else (os.cpu_count() or 1)
    except ValueError:
        raise ValueError(f"TELEOPKIT_WORKERS must be a whole number, got {text!r}") from None
    return max(1, count)


def _main_is_guarded() -> bool:
    """Whether the main module can be imported by a worker without running the caller's work."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if path is None:  # an interpreter prompt or a notebook: nothing is re-run
        return True
    try:
        return "__main__" in open(path, encoding="utf-8", errors="replace").read()
    except OSError:
        return False


def _share_cores(threads: int) -> None:
    """Start a worker with its share of the cores: ``threads`` for BLAS and for Clarabel."""
    threadpool_limits(threads)
    set_solver_threads(threads)


def _pool(count: int) -> Executor:
    if count not in _POOL:
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["teleopkit.certification.lmi.systems"])
        threads = max(1, (os.cpu_count() or 1) // count)
        _POOL[count] = ProcessPoolExecutor(count, mp_context=context, initializer=_share_cores,
                                           initargs=(threads,))
    return _POOL[count]


def _ready() -> None:
    """A task that does nothing: submitted to start a worker."""


def _parallel(count: int) -> bool:
    """Whether ``count`` solves can run on worker processes (else in this process)."""
    return count > 1 and "forkserver" in multiprocessing.get_all_start_methods()


def start_workers() -> None:
    """Start the worker processes in the background, ready for the first parallel solves.

    A worker takes a second or two to start (the fork server, then the LMI modules' imports);
    started at the beginning of a certification, that overlaps its first solves, which run
    in this process. Nothing happens with one worker or an unguarded main script.
    """
    count = workers()
    if _parallel(count) and _main_is_guarded():
        pool = _pool(count)
        for _ in range(count):
            pool.submit(_ready)


def map_solves(solve: Callable[..., _T], tasks: Sequence[tuple[Any, ...]]) -> list[_T]:
    """``[solve(*task) for task in tasks]``, on the worker processes when there are several.

    Parameters
    ----------
    solve : callable
        A module-level function (picklable).
    tasks : sequence of tuple
        Its arguments, one tuple per call.

    Returns
    -------
    list
        The results, in task order.
    """
    count = min(workers(), len(tasks))
    if count > 1 and not _main_is_guarded():
        warnings.warn("LMI solves run in one process: the main script has no "
                      "'if __name__ == \"__main__\":' guard, which worker processes need",
                      RuntimeWarning, stacklevel=2)
        count = 1
    if not _parallel(count):
        return [solve(*task) for task in tasks]
    return list(_pool(count).map(solve, *zip(*tasks, strict=True)))
