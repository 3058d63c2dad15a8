"""Files written so that a crash never leaves a half-written one: the one atomic write."""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["atomic_write"]


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
