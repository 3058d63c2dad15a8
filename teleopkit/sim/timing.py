"""The simulation clock: the default integration step and the control period.

The remote gains are held over each control period (the agent's sample time, 10 ms in the paper)
and the model is integrated at a fixed step that divides it.
"""

from __future__ import annotations

import math

__all__ = ["CONTROL_PERIOD", "DEFAULT_DT", "periods", "substeps"]

DEFAULT_DT = 0.0025
"""Default integration step (s): 4 steps of Butcher's fifth-order method
(:mod:`teleopkit.sim.tableau`) per 10 ms control period, 1.4e-6 to 1.8e-6 rad from a converged
solution over the paper's 40 s episodes. The local arm's damping (about -1030 1/s) puts the
method's stability limit near 3.3 ms on this model (at 3.33 ms the run drifts by 2e-2 rad)."""

CONTROL_PERIOD = 0.01
"""Default control period (s): the paper's agent sample time, over which gains are held."""


def _check_seconds(name: str, value: float) -> None:
    """Refuse a time that is not a positive finite number of seconds, in one line naming it."""
    try:
        finite = math.isfinite(value)
    except TypeError:
        raise TypeError(f"{name} must be a number of seconds, got {type(value).__name__}") from None
    if not (finite and value > 0):
        raise ValueError(f"{name} must be positive and finite, got {value:g} s")


def substeps(control_period: float, dt: float) -> int:
    """Integration steps per control period; the one check that the two fit together.

    Parameters
    ----------
    control_period : float
        Gain hold period in seconds.
    dt : float
        Integration step in seconds.

    Returns
    -------
    int
        ``control_period / dt``, a positive integer.

    Raises
    ------
    ValueError
        If either is not positive and finite, or the period is not a multiple of the step.
    TypeError
        If either is not a number.
    """
    _check_seconds("integration step", dt)
    _check_seconds("control period", control_period)
    count = round(control_period / dt)
    if count < 1 or abs(count * dt - control_period) > 1e-9 * control_period:
        raise ValueError(f"control period {control_period:g} s must be a positive multiple of "
                         f"the integration step {dt:g} s")
    return count


def periods(duration: float, control_period: float = CONTROL_PERIOD) -> int:
    """Control periods in a run; the one check that the run is a whole number of them.

    Parameters
    ----------
    duration : float
        Length of the run in seconds.
    control_period : float
        Gain hold period in seconds.

    Returns
    -------
    int
        ``duration / control_period``, at least 1.

    Raises
    ------
    ValueError
        If the duration or the period is not positive and finite, or the duration is not a
        whole number of periods.
    TypeError
        If either is not a number.
    """
    _check_seconds("duration", duration)
    _check_seconds("control period", control_period)
    count = round(duration / control_period)
    if count < 1 or abs(count * control_period - duration) > 1e-9 * duration:
        raise ValueError(f"duration {duration:g} s is not a whole number of control periods of "
                         f"{control_period:g} s")
    return count
