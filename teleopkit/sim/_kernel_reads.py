"""The compiled kernel's delayed reads of the channel histories.

They follow the rule of :class:`teleopkit.delays.history.ChannelHistory` (cubic Hermite
interpolation between grid samples, towards the current stage inside the current step, the
constant past before ``t = 0``), on the ring buffers of :func:`teleopkit.sim.kernel.advance`;
the tests compare the kernel with the numpy integrator that uses that class.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["delay_at", "delays_exceed", "hermite_scalar", "interpolate", "locate"]


@njit(cache=True, error_model="numpy", forceinline=True)
def hermite_scalar(x0: float, v0: float, x1: float, v1: float, span: float, u: float) -> float:
    """:func:`teleopkit.delays.history.hermite` for scalars."""
    u2 = u * u
    u3 = u2 * u
    return ((2 * u3 - 3 * u2 + 1) * x0 + (u3 - 2 * u2 + u) * span * v0
            + (3 * u2 - 2 * u3) * x1 + (u3 - u2) * span * v1)


@njit(cache=True, error_model="numpy", forceinline=True)
def locate(k: int, newest: int, frac: float, delay: float, dt: float,
           length: int) -> tuple[int, int, float, float, bool, bool]:
    """Locate a delayed read in a channel's history (:class:`~teleopkit.delays.ChannelHistory`).

    ``k`` is the newest stored grid step (ring slot ``newest``), ``frac`` the read time minus
    ``t_k`` in steps and ``delay`` the delay in seconds. Returns the ring slots ``(a, z)`` of the
    interval's ends, the fraction ``u`` and length ``span`` of the interval, whether the read falls
    inside the current step (then the interval ends at the integrator's stage, not at slot ``z``)
    and whether it falls before ``t = 0`` (constant past). Indices stay inside the buffer
    whatever the delay.
    """
    steps = k + frac - delay / dt
    inside = steps >= k
    back = min(max(k - math.floor(steps), 0), length - 2)  # steps from t_k to the start
    a = newest - back + (length if back > newest else 0)
    z = a + 1 if a + 1 < length else 0
    if inside:
        u = (steps - k) / frac if frac > 0.0 else 0.0
    else:
        u = steps - (k - back)
    return a, z, u, (frac * dt if inside else dt), inside, steps <= 0.0


@njit(cache=True, error_model="numpy", forceinline=True)
def interpolate(hist, lane, c, i, where, position, velocity, initial):
    """Read joint ``i`` of channel ``c`` at the place ``where`` from :func:`locate`.

    ``position`` and ``velocity`` are the sender's values at the stage.
    """
    a, z, u, span, inside, before = where
    n = initial.shape[2]
    x1 = position if inside else hist[lane, c, z, i]
    v1 = velocity if inside else hist[lane, c, z, n + i]
    value = hermite_scalar(hist[lane, c, a, i], hist[lane, c, a, n + i], x1, v1, span, u)
    return initial[lane, c, i] if before else value


@njit(cache=True, error_model="numpy", forceinline=True)
def delay_at(delays, scale, row, c, lane):
    """Channel ``c``'s delay of scenario ``lane`` at input row ``row``, in seconds.

    ``delays`` holds one column per scenario, or one shared column that ``scale`` multiplies
    (see :func:`teleopkit.sim.kernel.advance`).
    """
    return delays[row, c, lane if delays.shape[2] > 1 else 0] * scale[c, lane]


@njit(cache=True, error_model="numpy")
def delays_exceed(delays, scale, dt):
    """Whether every delay of a call (:func:`delay_at`) exceeds ``dt`` (none is NaN).

    A shared column is checked by its smallest value times the smallest scale: products of
    non-negative numbers round monotonically, so no product is smaller. A negative or NaN factor
    answers False, which is always safe (the reads are then made at every stage).
    """
    if delays.shape[2] > 1:
        for c in range(2):
            for row in range(delays.shape[0]):
                for lane in range(delays.shape[2]):
                    if not delays[row, c, lane] * scale[c, lane] > dt:
                        return False
        return True
    for c in range(2):
        low_delay, low_scale = math.inf, math.inf
        for row in range(delays.shape[0]):
            if not delays[row, c, 0] >= 0.0:
                return False
            low_delay = min(low_delay, delays[row, c, 0])
        for lane in range(scale.shape[1]):
            if not scale[c, lane] >= 0.0:
                return False
            low_scale = min(low_scale, scale[c, lane])
        if not low_delay * low_scale > dt:
            return False
    return True
