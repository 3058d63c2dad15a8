"""What the agent observes and earns at the end of each control period.

The observation is the paper's Section III state of the remote side (the damping error written
``theta_r - q_r``; the paper's eq. 6 has a typo) and the reward its quadratic cost of tracking
error, damping error and applied gains. Both are computed for a batch in compiled loops: for
one scenario, numpy's cost per call (some twenty small calls, about 13 µs) was four times the
simulated period itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from teleopkit.sim.state import FIELDS, Field, StateLayout

__all__ = ["OBSERVATION", "RewardWeights", "Score", "observation", "score"]

_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy"}

OBSERVATION = ("theta", "dtheta", "ql_delayed", "e_track", "int_e_track", "e_damp",
               "int_e_damp")
"""Blocks of an observation (``n`` values each), in order."""

_E_TRACK, _E_DAMP = OBSERVATION.index("e_track"), OBSERVATION.index("e_damp")
_BOUNDED = StateLayout(1).bounded  # state entries per joint that the failure check bounds


@njit(**_OPTIONS)
def _observe(state: np.ndarray, delayed_ql: np.ndarray, blocks: np.ndarray,
             obs: np.ndarray) -> None:
    """Write the blocks of :data:`OBSERVATION` of each state into ``obs``.

    ``blocks`` holds the first state entries of ``theta, theta', q_r, int e_track, int e_damp``.
    """
    n = delayed_ql.shape[1]
    theta, dtheta, qr, int_track, int_damp = blocks[0], blocks[1], blocks[2], blocks[3], blocks[4]
    for b in range(state.shape[0]):
        for j in range(n):
            motor = state[b, theta + j]
            obs[b, j] = motor
            obs[b, n + j] = state[b, dtheta + j]
            obs[b, 2 * n + j] = delayed_ql[b, j]
            obs[b, 3 * n + j] = motor - delayed_ql[b, j]
            obs[b, 4 * n + j] = state[b, int_track + j]
            obs[b, 5 * n + j] = motor - state[b, qr + j]
            obs[b, 6 * n + j] = state[b, int_damp + j]


@njit(**_OPTIONS)
def _squares(x: np.ndarray, b: int, start: int, count: int) -> float:
    """``sum_j x[b, start + j]^2`` over ``count`` entries."""
    total = 0.0
    for j in range(start, start + count):
        total += x[b, j] * x[b, j]
    return total


@njit(**_OPTIONS)
def _reward(track: np.ndarray, track_start: int, damp: np.ndarray, damp_start: int, n: int,
            action: np.ndarray, alpha: float, beta: float, gamma: float,
            out: np.ndarray) -> None:
    """``-(alpha ||e_track||^2 + beta ||e_damp||^2 + gamma ||a||^2)`` of each row into ``out``.

    The errors are the ``n`` columns of ``track`` and ``damp`` from the given starts.
    """
    for b in range(out.shape[0]):
        out[b] = -(alpha * _squares(track, b, track_start, n)
                   + beta * _squares(damp, b, damp_start, n)
                   + gamma * _squares(action, b, 0, action.shape[1]))


@njit(**_OPTIONS)
def _outside(state: np.ndarray, bounded: int, bound: float, failed: np.ndarray) -> int:
    """Mark the states that left the bound; count them.

    An entry that is not finite, or one of the first ``bounded`` beyond ``bound``
    (:attr:`~teleopkit.sim.state.StateLayout.bounded`), marks its state.
    """
    count = 0
    for b in range(state.shape[0]):
        failed[b] = False
        for j in range(state.shape[1]):
            value = state[b, j]
            if not math.isfinite(value) or (j < bounded and not abs(value) <= bound):
                failed[b] = True
                count += 1
                break
    return count


@njit(**_OPTIONS)
def _score(state: np.ndarray, delayed_ql: np.ndarray, action: np.ndarray, blocks: np.ndarray,
           alpha: float, beta: float, gamma: float, bound: float, obs: np.ndarray,
           reward: np.ndarray, failed: np.ndarray) -> int:
    """:func:`_observe`, :func:`_reward` of the errors it wrote, then :func:`_outside`."""
    n = delayed_ql.shape[1]
    _observe(state, delayed_ql, blocks, obs)
    _reward(obs, _E_TRACK * n, obs, _E_DAMP * n, n, action, alpha, beta, gamma, reward)
    return _outside(state, _BOUNDED * n, bound, failed)


@cache
def _blocks(n_joints: int) -> np.ndarray:
    """First entries of the state blocks the observation reads (see :func:`_observe`)."""
    layout = StateLayout(n_joints)
    names: tuple[Field, ...] = ("theta", "dtheta", "qr", "int_track", "int_damp")
    return np.array([layout.slice(name).start for name in names], dtype=np.int64)


def _rows(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``values`` broadcast to the leading ``shape``, as float rows of their last axis."""
    values = np.asarray(values, dtype=np.float64)
    return np.broadcast_to(values, (*shape, values.shape[-1])).reshape(-1, values.shape[-1])


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward ``-(alpha ||e_track||^2 + beta ||e_damp||^2 + gamma ||a||^2)``.

    The defaults make the three terms equal on average under the paper's fixed gains
    ``K_r = 10, B_r = 30`` on the paper scenario (16 scenarios of 40 s, seed 0), so each is about a
    third of the reward and the reward is about -3 per step there. Measured per-step means:
    ``||e_track||^2 = 0.0635 rad^2``, ``||e_damp||^2 = 1.29e-4 rad^2`` and ``||a||^2 = 2000``,
    hence ``alpha = 16 ~ 1/0.0635``, ``beta = 8000 ~ 1/1.29e-4`` and ``gamma = 5e-4 = 1/2000``.
    The damping error is concentrated in the first seconds (the initial deflection
    ``q_r(0) != theta_r(0)`` rings down; afterwards it is about 1e-8 rad^2), the tracking error
    follows the operator's decaying motion, and the gain term prices stiff, heavily damped
    settings (``||a||^2`` ranges from about 15 to 50 000 over the default box).

    Parameters
    ----------
    alpha : float
        Weight of the squared tracking error ``theta_r - q_l(t - T_l)``.
    beta : float
        Weight of the squared damping error ``theta_r - q_r``.
    gamma : float
        Weight of the squared applied gains.
    """

    alpha: float = 16.0
    beta: float = 8000.0
    gamma: float = 5e-4

    def __post_init__(self) -> None:
        for name in ("alpha", "beta", "gamma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"reward weight {name} must be finite and >= 0, got {value}")

    def reward(self, e_track: np.ndarray, e_damp: np.ndarray, action: np.ndarray) -> np.ndarray:
        """Reward of each scenario.

        Parameters
        ----------
        e_track : ndarray, shape (..., n)
            Tracking error.
        e_damp : ndarray, shape (..., n)
            Damping error.
        action : ndarray, shape (..., 2 n)
            Applied gains.

        Returns
        -------
        ndarray, shape (...)
            ``-(alpha ||e_track||^2 + beta ||e_damp||^2 + gamma ||a||^2)``.
        """
        shape = np.broadcast_shapes(*(np.shape(x)[:-1] for x in (e_track, e_damp, action)))
        track, damp, gains = (_rows(x, shape) for x in (e_track, e_damp, action))
        if track.shape[1] != damp.shape[1]:
            raise ValueError(f"tracking and damping errors need the same number of joints, "
                             f"got {track.shape[1]} and {damp.shape[1]}")
        out = np.empty(track.shape[0])
        _reward(track, 0, damp, 0, track.shape[1], gains, self.alpha, self.beta, self.gamma, out)
        return out.reshape(shape)


def observation(state: np.ndarray, delayed_ql: np.ndarray) -> np.ndarray:
    """The paper's observation of a batch of simulator states (the agent's input).

    Parameters
    ----------
    state : ndarray, shape (B, 12 n)
        Simulator states (:class:`~teleopkit.sim.state.StateLayout`).
    delayed_ql : ndarray, shape (B, n)
        Local positions as received by the remote side, ``q_l(t - T_l(t))``.

    Returns
    -------
    ndarray, shape (B, 7 n)
        The blocks of :data:`OBSERVATION`: ``[theta, theta', q_l(t - T_l),
        theta - q_l(t - T_l), int e_track, theta - q_r, int e_damp]``.
    """
    state, delayed_ql = _batch(state, delayed_ql)
    obs = np.empty((state.shape[0], len(OBSERVATION) * delayed_ql.shape[1]))
    _observe(state, delayed_ql, _blocks(delayed_ql.shape[1]), obs)
    return obs


def _batch(state: np.ndarray, delayed_ql: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Float states ``(B, 12 n)`` and delayed positions ``(B, n)`` that match."""
    state = np.asarray(state, dtype=np.float64)
    delayed_ql = np.asarray(delayed_ql, dtype=np.float64)
    n = delayed_ql.shape[-1] if delayed_ql.ndim == 2 else 0
    if state.ndim != 2 or n < 1 or state.shape != (delayed_ql.shape[0], len(FIELDS) * n):
        raise ValueError(f"states (B, 12 n) and delayed positions (B, n) do not match: shapes "
                         f"{state.shape} and {delayed_ql.shape}")
    return state, delayed_ql


class Score(NamedTuple):
    """What a batch observes and earns at the end of a control period.

    Attributes
    ----------
    obs : ndarray, shape (B, 7 n)
        Observations (:func:`observation`).
    reward : ndarray, shape (B,)
        Rewards (:meth:`RewardWeights.reward` of the applied gains).
    failed : ndarray of bool, shape (B,)
        States with an entry that is not finite or beyond the bound.
    failures : int
        How many states failed.
    """

    obs: np.ndarray
    reward: np.ndarray
    failed: np.ndarray
    failures: int


def score(state: np.ndarray, delayed_ql: np.ndarray, action: np.ndarray,
          weights: RewardWeights, bound: float) -> Score:
    """Observation, reward and failure check of a batch, in one compiled pass.

    Parameters
    ----------
    state : ndarray, shape (B, 12 n)
        Simulator states at the end of the period.
    delayed_ql : ndarray, shape (B, n)
        ``q_l(t - T_l(t))`` at that time.
    action : ndarray, shape (B, 2 n)
        Gains applied over the period.
    weights : RewardWeights
        Reward weights.
    bound : float
        Largest admissible absolute value of the motion and integrated errors
        (:attr:`~teleopkit.sim.state.StateLayout.bounded`); every entry must be finite.

    Returns
    -------
    Score
        Observations, rewards and failures.
    """
    state, delayed_ql = _batch(state, delayed_ql)
    action = np.asarray(action, dtype=np.float64)
    batch, n = delayed_ql.shape
    if action.shape != (batch, 2 * n):
        raise ValueError(f"applied gains must have shape {(batch, 2 * n)}, got {action.shape}")
    obs = np.empty((batch, len(OBSERVATION) * n))
    reward = np.empty(batch)
    failed = np.empty(batch, dtype=np.bool_)
    failures = _score(state, delayed_ql, action, _blocks(n), weights.alpha, weights.beta,
                      weights.gamma, bound, obs, reward, failed)
    return Score(obs, reward, failed, failures)

