"""Times with units: ``500ms``, ``0.5s`` or ``0.5`` (seconds), in specs and trace column names."""

from __future__ import annotations

import math
import re

__all__ = ["UNITS", "column_unit", "seconds"]

UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
"""Time units and their value in seconds."""

_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)\s*"
                     r"(s|ms|us)?\s*$")


def seconds(text: str, name: str) -> float:
    """A time in seconds from ``500ms``, ``0.5s`` or ``0.5`` (plain numbers are seconds).

    Parameters
    ----------
    text : str
        The time.
    name : str
        What it is, for the message (for example ``"constant delay"``).

    Returns
    -------
    float
        Seconds.

    Raises
    ------
    ValueError
        One line naming the time and the accepted forms.
    """
    match = _NUMBER.match(text)
    if match is None:
        raise ValueError(f"{name} must be a time such as 0.5, 0.5s or 500ms, got {text!r}")
    value = float(match.group(1)) * UNITS[match.group(2) or "s"]
    if math.isnan(value):
        raise ValueError(f"{name} must be a number, got {text!r}")
    return value


def column_unit(column: str) -> tuple[str, float]:
    """The base name of a column and its unit: ``delay_ms`` is ``("delay", 1e-3)``.

    Parameters
    ----------
    column : str
        A column name, with an optional ``_s``, ``_ms`` or ``_us`` suffix (seconds without).

    Returns
    -------
    tuple of (str, float)
        The name without the suffix (lower case) and the unit's value in seconds.
    """
    base, _, suffix = column.strip().lower().rpartition("_")
    if base and suffix in UNITS:
        return base, UNITS[suffix]
    return column.strip().lower(), 1.0
