"""Observations a tuner can adapt with: what the remote side measures, and no clock.

The paper's observation (:func:`~teleopkit.rl.scoring.observation`) lacks what an adaptive
tuner needs and carries what turns it into a schedule:

- it has no link velocity ``q_r'`` and so no deflection rate ``theta_r' - q_r'``: it sees a
  vibration of the elastic link only through its position;
- it has no measure of how much the operator moves (only the delayed position) and no measured
  delay;
- its integrals of the tracking and damping errors grow along an episode, a clock from which a
  policy learns *when* rather than *what* (the shipped tuner's gains are explained by time alone
  to 90 %).

:class:`AdaptiveObservation` gives, per joint, ``theta_r, theta_r', q_r', q_l(t - T_l)``, its
rate (the difference of the received positions over a control period), ``e_track, e_damp``,
the deflection rate ``e_damp'``, the levels of the operator's motion and of both errors
(``log10`` of exponential moving averages of their squares, time constant :data:`MEMORY`),
then the measured forward delay ``T_l(t)``: ``11 n + 1`` values, every one measurable on the
remote side, none growing with time.
"""

from __future__ import annotations

import math

import numpy as np

from teleopkit.sim.state import StateLayout

__all__ = ["MEMORY", "OBSERVATIONS", "AdaptiveObservation", "observation_size"]

MEMORY = 0.5
"""Time constant in seconds of the moving averages (the levels of motion and errors)."""

OBSERVATIONS = ("paper", "adaptive")
"""Observation kinds of the environments: the paper's (``7 n``) and :class:`AdaptiveObservation`."""

_FLOOR = 1e-12
"""Added to the averaged squares before the logarithm (rad^2, or rad^2/s^2)."""


def observation_size(kind: str, n_joints: int) -> int:
    """Values of an observation of ``kind`` (before a safety layer's run-time state).

    Parameters
    ----------
    kind : {"paper", "adaptive"}
        The observation.
    n_joints : int
        Joints.

    Returns
    -------
    int
        ``7 n`` or ``11 n + 1``.
    """
    if kind not in OBSERVATIONS:
        raise ValueError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {kind!r}")
    return 7 * n_joints if kind == "paper" else 11 * n_joints + 1


class AdaptiveObservation:
    """The adaptive observation of a batch, with the moving averages it keeps over an episode.

    Parameters
    ----------
    n_joints : int
        Joints.
    control_period : float
        Seconds between observations (the averages' step).
    """

    def __init__(self, n_joints: int, control_period: float) -> None:
        self.layout = StateLayout(n_joints)
        self.control_period = control_period
        self.keep = math.exp(-control_period / MEMORY)
        self._previous = np.zeros((0, n_joints))
        self._levels = np.zeros((0, 3, n_joints))

    def start(self, state: np.ndarray, delayed_ql: np.ndarray, delay: np.ndarray) -> np.ndarray:
        """The first observation of an episode (the averages start from the first values).

        Parameters
        ----------
        state : ndarray, shape (B, 12 n)
            Simulator states.
        delayed_ql : ndarray, shape (B, n)
            ``q_l(t - T_l)`` as received.
        delay : ndarray, shape (B,)
            The forward delay ``T_l(t)``.

        Returns
        -------
        ndarray, shape (B, 11 n + 1)
            The observation.
        """
        self._previous = np.array(delayed_ql, dtype=float)
        squares = self._squares(state, delayed_ql, np.zeros_like(self._previous))
        self._levels = squares
        return self._assemble(state, delayed_ql, np.zeros_like(self._previous), delay)

    def step(self, state: np.ndarray, delayed_ql: np.ndarray, delay: np.ndarray) -> np.ndarray:
        """The observation after one control period (see :meth:`start`).

        Parameters
        ----------
        state : ndarray, shape (B, 12 n)
            Simulator states.
        delayed_ql : ndarray, shape (B, n)
            ``q_l(t - T_l)`` as received.
        delay : ndarray, shape (B,)
            The forward delay ``T_l(t)``.

        Returns
        -------
        ndarray, shape (B, 11 n + 1)
            The observation.
        """
        rate = (delayed_ql - self._previous) / self.control_period
        self._previous = np.array(delayed_ql, dtype=float)
        squares = self._squares(state, delayed_ql, rate)
        self._levels = self.keep * self._levels + (1.0 - self.keep) * squares
        return self._assemble(state, delayed_ql, rate, delay)

    def _squares(self, state: np.ndarray, delayed_ql: np.ndarray,
                 rate: np.ndarray) -> np.ndarray:
        """Squares of the operator's received rate, the tracking and the damping errors."""
        get = self.layout.get
        theta = get(state, "theta")
        return np.stack([rate**2, (theta - delayed_ql) ** 2, (theta - get(state, "qr")) ** 2],
                        axis=1)

    def _assemble(self, state: np.ndarray, delayed_ql: np.ndarray, rate: np.ndarray,
                  delay: np.ndarray) -> np.ndarray:
        get = self.layout.get
        theta, dtheta = get(state, "theta"), get(state, "dtheta")
        qr, dqr = get(state, "qr"), get(state, "dqr")
        levels = np.log10(self._levels + _FLOOR)
        return np.concatenate([theta, dtheta, dqr, delayed_ql, rate, theta - delayed_ql,
                               theta - qr, dtheta - dqr, levels.reshape(len(state), -1),
                               np.reshape(delay, (-1, 1))], axis=1)
