"""Validation of the numeric arrays that systems and uncertainties are built from."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["as_float", "freeze_finite"]


def as_float(value: ArrayLike, name: str, kind: str = "array") -> NDArray[np.float64]:
    """Return ``value`` as a new float array, or raise a one-line ValueError.

    Parameters
    ----------
    value : array_like
        The input.
    name : str
        Its name in the message.
    kind : str
        What it should be, for the message (``"array"``, ``"matrix"``).

    Returns
    -------
    numpy.ndarray
        A float64 copy.
    """
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real numeric {kind} ({exc})") from None


def freeze_finite(arr: NDArray[np.float64], name: str) -> NDArray[np.float64]:
    """Make ``arr`` read-only after checking that every entry is finite.

    Parameters
    ----------
    arr : numpy.ndarray
        Float array (modified in place: no longer writeable).
    name : str
        Its name in the message.

    Returns
    -------
    numpy.ndarray
        ``arr`` itself.
    """
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf entries")
    arr.flags.writeable = False
    return arr
