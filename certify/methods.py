"""Registry of the LMI methods by name."""

from __future__ import annotations

from certify.conditions import LMIMethod
from certify.lmi import JENSEN, RECIPROCAL, WIRTINGER
from certify.small_gain import SMALL_GAIN

__all__ = ["AUTO_METHODS", "METHODS", "get_method"]

METHODS: dict[str, LMIMethod] = {m.name: m for m in (JENSEN, RECIPROCAL, WIRTINGER, SMALL_GAIN)}
"""Available methods: ``jensen``, ``rcc``, ``wirtinger`` and ``io``."""

AUTO_METHODS: tuple[str, ...] = ("wirtinger", "io")
"""Methods tried by ``method="auto"``; together they dominate the others (Wirtinger with
the reciprocally convex combination contains the Jensen and RCC functionals)."""


def get_method(name: str) -> LMIMethod:
    """Look a method up by name.

    Parameters
    ----------
    name : str
        One of :data:`METHODS`.

    Returns
    -------
    LMIMethod
        The method.

    Raises
    ------
    ValueError
        For an unknown name.
    """
    try:
        return METHODS[name]
    except KeyError:
        known = ", ".join([*METHODS, "auto"])
        raise ValueError(f"unknown method {name!r}; choose one of {known}") from None
