"""Progress of the long calls, shown as one status line on standard error.

The library says what a long call is doing with :mod:`logging` records at ``INFO`` level on
loggers under ``teleopkit`` (cells solved by the LMI search, candidates simulated by a gain
search, rows of a comparison). A public function that takes a ``progress`` argument shows them
while it runs (:func:`reports_progress`):

- ``None`` (the default): on a terminal, as one line rewritten in place; nothing when standard
  error is redirected;
- ``True``: always, one line per record where standard error is not a terminal (a notebook, a
  log file);
- ``False``: never.

A call made inside another follows the outer call's choice. The records reach your own logging
handlers whatever the choice, when you ask for them
(``logging.getLogger("teleopkit").setLevel(logging.INFO)``); otherwise only the status line gets
them.

Examples
--------
>>> from teleopkit.progress import show_progress
>>> with show_progress(False):  # silence every call inside
...     pass
"""

from __future__ import annotations

import contextlib
import logging
import math
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from functools import wraps
from inspect import signature
from typing import ParamSpec, TextIO, TypeVar

__all__ = ["LOGGER", "counting", "reports_progress", "show_progress"]

LOGGER = "teleopkit"
"""The logger whose records (and its children's) make the status line."""

_P = ParamSpec("_P")
_R = TypeVar("_R")
_X = TypeVar("_X")

_CHOSEN: ContextVar[bool | None] = ContextVar("teleopkit_progress", default=None)
"""Whether the outermost running call shows progress (None outside every call)."""


class _StatusLine(logging.Handler):
    """Progress as one status line on a terminal, rewritten in place; one line each elsewhere.

    Warnings and errors are left to the logging configuration: the status line makes way.
    """

    def __init__(self, stream: TextIO) -> None:
        super().__init__(logging.INFO)
        self.stream = stream
        self.start = time.monotonic()
        self.terminal = stream.isatty()
        self.pending = False  # a status line to clear

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno > logging.INFO:
            self.clear()
            return
        text = f"[{time.monotonic() - self.start:6.1f} s] {record.getMessage()}"
        if self.terminal:
            self.stream.write(f"\r\033[K{text[:shutil.get_terminal_size().columns - 1]}")
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self.pending = self.terminal

    def clear(self) -> None:
        """Erase the status line, if one is shown."""
        if self.pending:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self.pending = False

    def close(self) -> None:
        self.clear()
        super().close()


class _Onward(logging.Handler):
    """Records at or above a level, handed on to a logger (its handlers, then its parents')."""

    def __init__(self, level: int, target: logging.Logger) -> None:
        super().__init__(level)
        self.target = target

    def emit(self, record: logging.LogRecord) -> None:
        self.target.handle(record)


@contextlib.contextmanager
def _attached(handler: logging.Handler) -> Iterator[None]:
    """Send the library's records to ``handler`` while the block runs.

    Records nobody asked for (below the level the logger had) go to ``handler`` only; the others
    reach the logging configuration as they would without it.
    """
    log = logging.getLogger(LOGGER)
    level, propagate = log.level, log.propagate
    added = [handler]
    if not log.isEnabledFor(logging.INFO):
        if propagate and log.parent is not None:
            added.append(_Onward(log.getEffectiveLevel(), log.parent))
        log.setLevel(logging.INFO)
        log.propagate = False
    for each in added:
        log.addHandler(each)
    try:
        yield
    finally:
        for each in added:
            log.removeHandler(each)
        log.setLevel(level)
        log.propagate = propagate
        handler.close()


@contextlib.contextmanager
def show_progress(progress: bool | None = None) -> Iterator[None]:
    """Show the library's progress records on standard error while the block runs.

    Parameters
    ----------
    progress : bool, optional
        ``None``: on a terminal only; ``True``: always; ``False``: never. Inside another
        ``show_progress`` block (a call made by a call), the outer block's choice holds.

    Yields
    ------
    None
        While the block runs.
    """
    if _CHOSEN.get() is not None:
        yield
        return
    shown = sys.stderr.isatty() if progress is None else bool(progress)
    token = _CHOSEN.set(shown)
    try:
        with _attached(_StatusLine(sys.stderr)) if shown else contextlib.nullcontext():
            yield
    finally:
        _CHOSEN.reset(token)


def reports_progress(function: Callable[_P, _R]) -> Callable[_P, _R]:
    """Decorator: run ``function`` inside :func:`show_progress` of its ``progress`` argument.

    Parameters
    ----------
    function : callable
        A function with a ``progress: bool | None = None`` parameter.

    Returns
    -------
    callable
        The function, showing its progress as asked.
    """
    parameters = signature(function)

    @wraps(function)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        chosen = parameters.bind(*args, **kwargs).arguments.get("progress")
        with show_progress(chosen):
            return function(*args, **kwargs)

    return wrapper


def counting(log: logging.Logger, label: str, budget: int
             ) -> Callable[[Callable[[_X], float]], Callable[[_X], float]]:
    """Decorator of an objective: log each evaluation with its count and the best value so far.

    Parameters
    ----------
    log : logging.Logger
        Where the records go.
    label : str
        What is being searched, for the records.
    budget : int
        Evaluations the search may make (its stopping rule may go a few over).

    Returns
    -------
    callable
        Turns an objective (for example of :func:`scipy.optimize.minimize`) into one that logs
        ``label: evaluation i (budget b), best cost c``.
    """
    def decorate(function: Callable[[_X], float]) -> Callable[[_X], float]:
        calls, best = 0, math.inf

        @wraps(function)
        def counted(x: _X) -> float:
            nonlocal calls, best
            value = function(x)
            calls, best = calls + 1, min(best, value)
            log.info("%s: evaluation %d (budget %d), best cost %.5g", label, calls, budget, best)
            return value

        return counted

    return decorate
