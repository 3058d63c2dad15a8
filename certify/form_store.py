"""Compiled LMI problems shared between processes through a directory.

Building and compiling the cvxpy problem of a method for one system structure (cvxpy's DPP
canonicalisation) takes about half a second on a two-joint teleoperator's cell, and the worker
processes that solve the cells of a cover side by side need the same dozen problems: each
compiled every one of them again. A process that shares a directory (:func:`share_forms`)
writes each problem it compiles there, pickled before its first solve (so without a solver:
every solve makes a fresh one anyway), and looks there before compiling one itself; reading
one back takes under a tenth of a second. The directory belongs to whoever set it up (a pool
of worker processes, for the length of its life): problems compiled by one version of cvxpy
are read back only by the processes of that run.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["load_form", "save_form", "share_forms", "shared_directory"]

_directory: Path | None = None


def share_forms(directory: str | os.PathLike[str] | None) -> None:
    """Share compiled problems through ``directory`` from now on (``None``: stop sharing).

    Parameters
    ----------
    directory : path or None
        An existing directory that only this run's processes write to.

    Raises
    ------
    ValueError
        If ``directory`` is not an existing directory.
    """
    global _directory
    path = None if directory is None else Path(directory)
    if path is not None and not path.is_dir():
        raise ValueError(f"cannot share compiled problems through {path}: not a directory")
    _directory = path


def shared_directory() -> Path | None:
    """The directory compiled problems are shared through (``None``: none).

    Returns
    -------
    pathlib.Path or None
        The directory of :func:`share_forms`.
    """
    return _directory


def _file(key: tuple[Any, ...]) -> Path | None:
    if _directory is None:
        return None
    return _directory / f"{hashlib.sha256(repr(key).encode()).hexdigest()[:32]}.pickle"


def load_form(key: tuple[Any, ...]) -> Any | None:
    """The problem another process saved under ``key``, if the directory holds one.

    Parameters
    ----------
    key : tuple
        What identifies the problem (its repr is hashed: it must be deterministic).

    Returns
    -------
    object or None
        The unpickled problem, or ``None`` (no directory, nothing saved yet, or unreadable).
    """
    path = _file(key)
    if path is None:
        return None
    try:
        with path.open("rb") as stream:
            return pickle.load(stream)
    except (OSError, EOFError, pickle.UnpicklingError):  # OSError: none saved yet
        return None


def save_form(key: tuple[Any, ...], form: Any) -> None:
    """Save a compiled problem under ``key`` for the other processes (atomically).

    Parameters
    ----------
    key : tuple
        What identifies the problem.
    form : object
        The picklable problem. Nothing is saved without a shared directory, or if one is
        already there; a directory that cannot be written leaves the problem unshared.
    """
    path = _file(key)
    if path is None or path.exists():
        return
    try:
        handle, name = tempfile.mkstemp(dir=path.parent, suffix=".part")
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):  # a full directory: the problem stays unshared
            with os.fdopen(handle, "wb") as stream:
                pickle.dump(form, stream, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(name, path)
    finally:
        Path(name).unlink(missing_ok=True)
