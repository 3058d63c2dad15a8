"""Files written so that a crash never leaves a half-written one, and directories one run owns.

:func:`atomic_write` is the one atomic write; :func:`run_lock` keeps a second run out of a
directory (or an output) while one uses it, and recognises the lock of a run that was killed.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import uuid
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RunLocked", "atomic_write", "check_unlocked", "lock_holder", "run_lock",
           "write_csv"]


def atomic_write(path: str | Path, write: Callable[[Path], Any]) -> None:
    """Write ``path`` through a temporary file in the same directory, then rename it into place.

    The temporary file has a unique name (concurrent writers never share one), is flushed to
    disk before the rename (:func:`os.replace`, atomic on POSIX and Windows), and is removed if
    writing fails. A reader therefore sees either the previous complete file or the new one.

    Parameters
    ----------
    path : str or Path
        Destination file.
    write : callable
        ``write(temporary_path)`` writes the content.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        write(tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_csv(path: str | Path, columns: Mapping[str, np.ndarray]) -> None:
    """Write equal-length numeric columns as a CSV file, atomically, without pandas.

    Numbers are written in the shortest form that reads back to the same float (as pandas
    does), so the file round-trips exactly.

    Parameters
    ----------
    path : str or Path
        Destination file.
    columns : mapping of str to ndarray, shape (N,)
        Column names and values, in order.
    """
    matrix = np.column_stack([np.asarray(v, dtype=float) for v in columns.values()]).tolist()
    lines = [",".join(columns), *(",".join(map(repr, row)) for row in matrix)]
    atomic_write(path, lambda tmp: tmp.write_text("\n".join(lines) + "\n"))


class RunLocked(RuntimeError):
    """Another live run holds the lock (the message names it)."""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        return True
    return True


def lock_holder(lock: str | Path) -> dict[str, Any] | None:
    """The live run that holds ``lock`` (its ``pid`` and ``host``), or None.

    Parameters
    ----------
    lock : str or Path
        A lock file of :func:`run_lock`.

    Returns
    -------
    dict or None
        None when there is no lock, or it was left by a run whose process is gone.
    """
    lock = Path(lock)
    try:
        holder = json.loads(lock.read_text())
        pid, host = int(holder["pid"]), str(holder["host"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if host != socket.gethostname():  # another machine's run: assume it lives
        return holder
    return holder if pid != os.getpid() and _alive(pid) else None


def check_unlocked(lock: str | Path, what: str) -> None:
    """Refuse at once if a live run holds ``lock`` (a lock left by a killed run is no lock).

    Parameters
    ----------
    lock : str or Path
        A lock file of :func:`run_lock`.
    what : str
        What is locked, for the message.

    Raises
    ------
    RunLocked
        One line naming the run that holds it.
    """
    holder = lock_holder(lock)
    if holder is not None:
        raise RunLocked(f"{what} is in use by another run (process {holder['pid']} on "
                        f"{holder['host']}); wait for it to end or choose another output")


@contextlib.contextmanager
def run_lock(lock: str | Path, what: str) -> Iterator[None]:
    """Hold the lock file ``lock`` while the block runs; refuse at once if a live run holds it.

    The lock records the process id and host. A lock left by a run that was killed (its process
    is gone) is taken over; the lock is removed when the block ends, however it ends.

    Parameters
    ----------
    lock : str or Path
        The lock file (its directory must exist).
    what : str
        What is locked, for the message (for example ``"runs/train"``).

    Yields
    ------
    None
        While the lock is held.

    Raises
    ------
    RunLocked
        If a live run holds it: one line naming the run.
    """
    path = Path(lock)
    record = json.dumps({"pid": os.getpid(), "host": socket.gethostname()})
    for _ in range(2):
        try:
            with open(path, "x", encoding="utf-8") as handle:
                handle.write(record)
            break
        except FileExistsError:
            check_unlocked(path, what)
            path.unlink(missing_ok=True)  # a killed run's lock
    else:
        raise RunLocked(f"{what}: could not take the lock {path}")
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
