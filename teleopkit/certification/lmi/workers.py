"""Independent LMI solves on the local cores.

Cells of a cover, and the vertex checks before a split, are independent problems: they are
solved by one pool of worker processes, started by a fork server that imports the LMI modules
once (forking the caller directly can deadlock on locks its threads hold) and shut down when the
interpreter exits. The number of workers is set explicitly, by ``certify_gains(...,
workers=N)`` or ``teleopkit certify --workers N`` (both enter :func:`using_workers`); without
it, the environment variable ``TELEOPKIT_WORKERS``, else ``os.cpu_count()`` (``1`` solves in
this process). Results come back in the order of the tasks, so a cover is the same whatever the
number of workers.

Each worker gets its share of the cores (:func:`threads_per_worker`) for BLAS, through
:mod:`threadpoolctl` when it starts, and for Clarabel's linear algebra, passed with each solve
(``threads=`` of :func:`certify.certify_delay`). Both default to every core, and on the small
dense blocks of these LMIs threads cost more than they give: with two workers each running two
BLAS and two solver threads on two cores, a level of cells took as long as solving them one
after the other in one process.

A search whose result is needed later (the limiting gain vertex's delay margin) runs beside the
covers (:class:`Background`), on the workers they leave idle.

The processes of a pool (and the caller) share the cvxpy problems they compile through a
temporary directory that lives as long as the pool (:mod:`certify.form_store`): a cover needs
about a dozen of them, half a second of compiling each, and every process used to compile each
one again.

A worker starts by importing the caller's main module, as every non-fork start of
:mod:`multiprocessing` does, so a script must keep its work under
``if __name__ == "__main__":``. A script file without that guard would run again in each worker;
its solves run in the calling process instead, with a warning. From a notebook or the
interpreter prompt nothing is re-run.
"""

from __future__ import annotations

import ast
import atexit
import contextlib
import contextvars
import functools
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextvars import ContextVar
from typing import Any, Generic, TypeVar, cast

from threadpoolctl import threadpool_limits

__all__ = ["Background", "map_solves", "shutdown_workers", "start_workers",
           "threads_per_worker", "using_workers", "workers"]

_T = TypeVar("_T")
_CHOSEN: ContextVar[int | None] = ContextVar("teleopkit_lmi_workers", default=None)


class _Pool:
    """The one pool of worker processes (replaced when another size is asked for)."""

    executor: ProcessPoolExecutor | None = None
    size = 0
    forms = ""  # the directory its processes share compiled problems through
    shared = False  # whether this process shares them too


def _count(value: int | str, source: str) -> int:
    try:
        count = int(value)
    except ValueError:
        raise ValueError(f"{source} must be a whole number, got {value!r}") from None
    if count < 1:
        raise ValueError(f"{source} must be at least 1, got {count}")
    return count


def workers() -> int:
    """Number of worker processes in force.

    The count of the enclosing :func:`using_workers`, else ``TELEOPKIT_WORKERS``, else the core
    count.

    Returns
    -------
    int
        At least 1.
    """
    chosen = _CHOSEN.get()
    if chosen is not None:
        return chosen
    text = os.environ.get("TELEOPKIT_WORKERS", "")
    return _count(text, "TELEOPKIT_WORKERS") if text else max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def using_workers(count: int | None) -> Iterator[None]:
    """Solve with ``count`` worker processes inside the block (None: the default).

    Parameters
    ----------
    count : int or None
        Worker processes (1: in this process).

    Yields
    ------
    None
        While the block runs.
    """
    token = _CHOSEN.set(None if count is None else _count(count, "workers"))
    try:
        yield
    finally:
        _CHOSEN.reset(token)


def threads_per_worker(count: int) -> int:
    """Threads each of ``count`` side-by-side solves may use: its share of the cores.

    Parameters
    ----------
    count : int
        Solves running at once.

    Returns
    -------
    int
        ``os.cpu_count() // count`` (at least 1) for several; 1 for a solve alone, which on
        these LMIs is faster than the solver's default of every core (a two-joint cell: 0.66 s
        with one thread, 0.92 s with two, on two cores).
    """
    return max(1, (os.cpu_count() or 1) // count) if count > 1 else 1


def _main_is_guarded() -> bool:
    """Whether the main module can be imported by a worker without running the caller's work.

    True when the script has a top-level ``if __name__ == "__main__":`` block (or there is no
    script: an interpreter prompt or a notebook re-runs nothing).
    """
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if path is None:
        return True
    try:
        tree = ast.parse(open(path, encoding="utf-8", errors="replace").read())
    except (OSError, SyntaxError, ValueError):
        return False
    return any(isinstance(node, ast.If) and _is_main_test(node.test) for node in tree.body)


def _is_main_test(test: ast.expr) -> bool:
    """Whether ``test`` is ``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = {ast.unparse(test.left), ast.unparse(test.comparators[0])}
    return sides in ({"__name__", "'__main__'"}, {"__name__", '"__main__"'})


def _start_worker(threads: int, forms: str) -> None:
    """Start a worker: its share of the cores for BLAS, the pool's compiled problems.

    The solver's share of the cores is passed with each solve. Ctrl-C, which a terminal sends
    to every process of the group, is left to the main process: it keeps what was proven and
    stops the pool, so a worker neither dies with a traceback nor cuts its solve's answer short.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threadpool_limits(threads)
    _share_forms(forms)


def _share_forms(directory: str | None) -> None:
    """Share this process's compiled problems through ``directory`` (None: stop).

    Imported on first use: :mod:`certify` imports cvxpy (over half a second), which the closed
    form's answer does not need, and which would hold back the workers' start.
    """
    from certify.form_store import share_forms

    share_forms(directory)


def _share_here() -> None:
    """Let this process use and extend the pool's compiled problems, once there is a pool."""
    if _Pool.executor is not None and not _Pool.shared:
        _share_forms(_Pool.forms)
        _Pool.shared = True


def _pool(count: int) -> ProcessPoolExecutor:
    """The pool, with ``count`` workers (the previous one is shut down if its size differs)."""
    if _Pool.executor is None or _Pool.size != count:
        shutdown_workers()
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["teleopkit.certification.lmi.systems"])
        _Pool.forms, _Pool.shared = tempfile.mkdtemp(prefix="teleopkit-lmi-"), False
        _Pool.executor = ProcessPoolExecutor(count, mp_context=context,
                                             initializer=_start_worker,
                                             initargs=(threads_per_worker(count), _Pool.forms))
        _Pool.size = count
    return _Pool.executor


@atexit.register
def shutdown_workers() -> None:
    """Stop the worker processes, if any (also done when the interpreter exits)."""
    if _Pool.executor is not None:
        _Pool.executor.shutdown(wait=True, cancel_futures=True)
        _Pool.executor, _Pool.size = None, 0
        if _Pool.shared:
            _share_forms(None)
        _Pool.shared = False
        shutil.rmtree(_Pool.forms, ignore_errors=True)


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
        _share_here()  # while the workers start


def map_solves(solve: Callable[..., _T], tasks: Sequence[tuple[Any, ...]],
               share_cores: bool = False) -> list[_T]:
    """``[solve(*task) for task in tasks]``, on the worker processes when there are several.

    Parameters
    ----------
    solve : callable
        A module-level function (picklable).
    tasks : sequence of tuple
        Its arguments, one tuple per call.
    share_cores : bool
        Pass each call ``threads=`` its share of the cores (:func:`threads_per_worker`; one
        thread when the calls run one after the other in this process).

    Returns
    -------
    list
        The results, in task order.
    """
    count = workers()
    parallel = min(count, len(tasks)) > 1
    if parallel and not _main_is_guarded():
        warnings.warn("LMI solves run in one process: the main script has no "
                      "'if __name__ == \"__main__\":' guard, which worker processes need",
                      RuntimeWarning, stacklevel=2)
        parallel = False
    parallel = parallel and _parallel(count)
    if share_cores:
        solve = functools.partial(solve, threads=threads_per_worker(count if parallel else 1))
    pool = _pool(count) if parallel else None
    _share_here()
    if pool is None:
        return [solve(*task) for task in tasks]
    return list(pool.map(solve, *zip(*tasks, strict=True)))


class Background(Generic[_T]):
    """A search whose solves run beside the caller's, for a result needed later.

    With several workers (and a guarded main script) ``call(*args)`` runs at once on a thread of
    this process, in the caller's context (its :func:`using_workers` count), and its
    :func:`map_solves` share the pool with the caller's: it fills the workers the caller leaves
    idle (a level of one cell, a solve in this process). Otherwise it runs when :meth:`result`
    is first called. The result is the same either way.

    Parameters
    ----------
    call : callable
        The search (it may call :func:`map_solves`).
    *args
        Its arguments.
    """

    def __init__(self, call: Callable[..., _T], *args: Any) -> None:
        self._call = functools.partial(contextvars.copy_context().run, call, *args)
        self._outcome: tuple[bool, Any] | None = None
        self._thread: threading.Thread | None = None
        if _parallel(workers()) and _main_is_guarded():
            # a daemon: an interrupted certification does not wait for it at exit
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name="teleopkit-lmi-background")
            self._thread.start()

    def _run(self) -> None:
        try:
            self._outcome = (True, self._call())
        except BaseException as exc:  # re-raised by result(), in the caller's thread
            self._outcome = (False, exc)

    def result(self) -> _T:
        """The search's result (waits for it; raises what it raised).

        Returns
        -------
        object
            What ``call(*args)`` returned.
        """
        if self._thread is not None:
            self._thread.join()
        elif self._outcome is None:
            self._run()
        done, value = cast(tuple[bool, Any], self._outcome)
        if not done:
            raise value
        return value
