"""Channel history: the sender's samples on the integration grid, read back at ``t - T(t)``.

The sender's position and velocity are stored at every grid point ``t_k = k dt``; a read at time
``s = t - T(t)`` interpolates with the cubic Hermite polynomial through the two neighbouring
samples and their derivatives, which is exact on cubics (an interpolation error of order four). A
read inside the current step (``T < dt``) interpolates towards the integrator's current stage, so
zero delay returns the current value exactly. Before the first sample (``s <= 0``) the receiver
holds the initial value (constant past).

This module holds the readable numpy implementation used by :mod:`teleopkit.sim.numpy_integrator`;
the compiled kernel in :mod:`teleopkit.sim.kernel` implements the same rule and is tested against
it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ChannelHistory", "hermite"]


def hermite(x0: np.ndarray, v0: np.ndarray, x1: np.ndarray, v1: np.ndarray,
            span: np.ndarray | float, u: np.ndarray | float) -> np.ndarray:
    """Cubic Hermite interpolation on ``[0, span]`` at the fraction ``u`` in ``[0, 1]``.

    Parameters
    ----------
    x0, v0 : ndarray
        Value and derivative at the start.
    x1, v1 : ndarray
        Value and derivative at the end.
    span : float or ndarray
        Length of the interval.
    u : float or ndarray
        Fraction of the interval.

    Returns
    -------
    ndarray
        The interpolated value.

    Examples
    --------
    >>> float(hermite(0.0, 1.0, 1.0, 1.0, 1.0, 0.25))
    0.25
    """
    u2 = u * u
    u3 = u2 * u
    return ((2 * u3 - 3 * u2 + 1) * x0 + (u3 - 2 * u2 + u) * span * v0
            + (3 * u2 - 2 * u3) * x1 + (u3 - u2) * span * v1)


class ChannelHistory:
    """History of a batch of vector signals with delayed read-out.

    Parameters
    ----------
    initial : ndarray, shape (B, n)
        Value at ``t = 0``, held for all earlier times.
    dt : float
        Grid step in seconds.
    bound : float
        Largest delay that will be read (sizes the ring buffer).
    """

    def __init__(self, initial: np.ndarray, dt: float, bound: float) -> None:
        self.initial = np.array(initial, dtype=float)
        self.dt = dt
        self.length = math.ceil(bound / dt) + 2
        self.position = np.repeat(self.initial[None], self.length, axis=0)
        self.velocity = np.zeros_like(self.position)
        self.index = 0

    def record(self, position: np.ndarray, velocity: np.ndarray) -> None:
        """Store the sample of the next grid point ``t_{k+1}``.

        Parameters
        ----------
        position : ndarray, shape (B, n)
            The signal's value at ``t_{k+1}``.
        velocity : ndarray, shape (B, n)
            The signal's derivative at ``t_{k+1}`` (used by the Hermite interpolation).
        """
        self.index += 1
        self.position[self.index % self.length] = position
        self.velocity[self.index % self.length] = velocity

    def read(self, fraction: float, delay: np.ndarray, latest: tuple[np.ndarray, np.ndarray],
             ) -> np.ndarray:
        """Return the signal at ``t - delay``, ``t = t_k + fraction dt``, ``t_k`` the newest sample.

        Parameters
        ----------
        fraction : float
            Time since the newest sample, in steps, in ``[0, 1]``.
        delay : ndarray, shape (B,)
            Delay of each scenario.
        latest : tuple of ndarray, shape (B, n)
            The signal's value and derivative at ``t`` (the integrator's current stage).

        Returns
        -------
        ndarray, shape (B, n)
            The delayed signal.
        """
        k = self.index
        steps = k + fraction - np.asarray(delay) / self.dt
        j = np.floor(steps).astype(int)
        newest = k % self.length
        j_old = np.minimum(j, k - 1)
        u_old = (steps - j_old)[:, None]
        old = hermite(self.position[j_old % self.length, self._rows()],
                      self.velocity[j_old % self.length, self._rows()],
                      self.position[(j_old + 1) % self.length, self._rows()],
                      self.velocity[(j_old + 1) % self.length, self._rows()], self.dt, u_old)
        u_new = ((steps - k) / fraction)[:, None] if fraction > 0 else 0.0
        new = hermite(self.position[newest], self.velocity[newest], latest[0], latest[1],
                      fraction * self.dt, u_new)
        out = np.where((j >= k)[:, None], new, old)
        return np.where((steps <= 0)[:, None], self.initial, out)

    def _rows(self) -> np.ndarray:
        return np.arange(self.initial.shape[0])
