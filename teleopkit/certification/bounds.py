"""Delay bounds of a certificate: the one check of ``T_l*`` and ``T_r*``."""

from __future__ import annotations

import math

__all__ = ["check_delay_bounds"]


def check_delay_bounds(tl_max: float, tr_max: float) -> tuple[float, float]:
    """Return the delay bounds ``(T_l*, T_r*)`` as floats if both are positive and finite.

    Parameters
    ----------
    tl_max, tr_max : float
        Bounds of the forward and backward delays in seconds.

    Returns
    -------
    tuple of float
        ``(T_l*, T_r*)``.

    Raises
    ------
    ValueError
        One line naming the bad bound.
    """
    for name, value in (("T_l*", tl_max), ("T_r*", tr_max)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"delay bound {name} must be positive and finite, got {value}")
    return float(tl_max), float(tr_max)
