"""Delay bounds of a certificate: the one check of ``T_l*``, ``T_r*`` and the minimum delays."""

from __future__ import annotations

import math

__all__ = ["check_delay_bounds", "check_delay_floors"]


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


def check_delay_floors(tl_min: float, tr_min: float, tl_max: float,
                       tr_max: float) -> tuple[float, float]:
    """Return the minimum delays ``(T_l_min, T_r_min)`` if ``0 <= T_i_min < T_i*``.

    Parameters
    ----------
    tl_min, tr_min : float
        Lower bounds of the forward and backward delays in seconds.
    tl_max, tr_max : float
        The upper bounds (already checked by :func:`check_delay_bounds`).

    Returns
    -------
    tuple of float
        ``(T_l_min, T_r_min)``.

    Raises
    ------
    ValueError
        One line naming the bad bound.
    """
    for name, value, upper in (("T_l_min", tl_min, tl_max), ("T_r_min", tr_min, tr_max)):
        if not (math.isfinite(value) and 0 <= value < upper):
            raise ValueError(f"minimum delay {name} must lie in [0, {upper:g}) s (below the "
                             f"upper bound), got {value}")
    return float(tl_min), float(tr_min)
