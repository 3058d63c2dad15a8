"""Files written so that a crash never leaves a half-written one: the one atomic write."""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["atomic_write", "write_csv"]


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
