"""Independent LMI solves on the local cores.

Cells of a cover, and the vertex checks before a split, are independent problems: they are
solved by a pool of worker processes, one per core, started by a fork server that imports the
LMI modules once (forking the caller directly can deadlock on locks its threads hold). The
number of workers is ``os.cpu_count()`` unless the environment variable ``TELEOPKIT_WORKERS``
sets it (``1`` solves in this process). Results come back in the order of the tasks, so a cover
is the same whatever the number of workers.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, TypeVar

__all__ = ["map_solves", "workers"]

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


def _pool(count: int) -> Executor:
    if count not in _POOL:
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["teleopkit.certification.lmi"])
        _POOL[count] = ProcessPoolExecutor(count, mp_context=context)
    return _POOL[count]


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
    if count <= 1 or "forkserver" not in multiprocessing.get_all_start_methods():
        return [solve(*task) for task in tasks]
    return list(_pool(count).map(solve, *zip(*tasks, strict=True)))
