"""Delays that jump: their left limits, which a fixed-step integrator needs at the step ends.

A profile that is constant between switching times (:class:`~teleopkit.delays.SwitchingDelay`,
:class:`~teleopkit.delays.SquareWaveDelay`, :class:`~teleopkit.delays.PiecewiseDelay`) has
``jumps = True`` and a method ``sample_left(t)``: the delays just before ``t``, which differ from
``sample(t)`` only at a switching time (there ``sample`` gives the new value). A step that ends at
a switch integrates the old delay over its whole interval, so its last stage must read the left
limit and the next step's first stage the new value; with both, a jump on the step grid costs the
Runge–Kutta method none of its order (:class:`~teleopkit.sim.simulator.Simulator`). A profile
without ``jumps`` is continuous and its left limit is its value.
"""

from __future__ import annotations

from typing import Protocol, cast

import numpy as np

from teleopkit.delays.profiles import DelayProfile

__all__ = ["has_jumps", "sample_left"]


class _Jumping(Protocol):
    def sample_left(self, t: np.ndarray) -> np.ndarray: ...


def has_jumps(profile: DelayProfile) -> bool:
    """Whether ``profile`` declares jumps (``jumps = True`` and a ``sample_left`` method).

    Parameters
    ----------
    profile : DelayProfile
        A delay profile.

    Returns
    -------
    bool
        False for a profile without a ``jumps`` attribute: it is taken to be continuous.
    """
    return bool(getattr(profile, "jumps", False))


def sample_left(profile: DelayProfile, t: np.ndarray) -> np.ndarray:
    """The delays of ``profile`` just before the times ``t`` (its left limits).

    Parameters
    ----------
    profile : DelayProfile
        A delay profile.
    t : ndarray, shape (S,)
        Times in seconds.

    Returns
    -------
    ndarray, shape (S, B)
        ``profile.sample_left(t)`` for a profile with jumps, else ``profile.sample(t)``.
    """
    if has_jumps(profile):
        return cast(_Jumping, profile).sample_left(t)
    return profile.sample(t)
