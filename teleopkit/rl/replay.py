"""Replay storage of the TD3 learner, and the window that makes ``n``-step transitions.

The buffer is preallocated numpy arrays with seeded sampling. An ``n``-step transition
``(s_t, a_t, R, s_{t+k}, k)`` carries the discounted reward sum
``R = sum_{i<k} discount^i r_{t+i}`` over ``k = n`` steps, or fewer where the episode ended
first; the critic's target bootstraps with ``discount^k`` (Sutton & Barto 2018, section 7.1;
Hessel et al. 2018 for its use with replay). Credit then travels ``n`` steps per update instead
of one: an episode here is 4000 control periods, and at discount 0.99 a one-step target needs
hundreds of updates to carry the opening transient's cost back to the gains that caused it.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch

__all__ = ["Batch", "NStepWindow", "ReplayBuffer"]


class Batch(NamedTuple):
    """A minibatch of transitions as float32 tensors (batch axis first).

    Attributes
    ----------
    obs : torch.Tensor, shape (B, obs_dim)
        Observations.
    action : torch.Tensor, shape (B, act_dim)
        Applied (projected) gains.
    reward : torch.Tensor, shape (B,)
        Rewards.
    next_obs : torch.Tensor, shape (B, obs_dim)
        Observations after the step.
    terminated : torch.Tensor, shape (B,)
        1 where the episode ended by failure (no bootstrapping), else 0.
    steps : torch.Tensor, shape (B,)
        Steps ``k`` the transition spans (1 for a one-step transition): ``reward`` is their
        discounted sum and ``next_obs`` the observation after them.
    """

    obs: torch.Tensor
    action: torch.Tensor
    reward: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor
    steps: torch.Tensor


class ReplayBuffer:
    """Preallocated ring buffer of transitions with seeded uniform sampling.

    Parameters
    ----------
    capacity : int
        Largest number of transitions kept (the oldest are overwritten).
    obs_dim, act_dim : int
        Observation and action sizes.
    seed : int or numpy.random.Generator
        Seed of the sampling generator.
    """

    _FIELDS = ("obs", "action", "reward", "next_obs", "terminated", "steps")

    def __init__(self, capacity: int, obs_dim: int, act_dim: int,
                 seed: int | np.random.Generator = 0) -> None:
        if capacity < 1:
            raise ValueError(f"replay capacity must be at least 1, got {capacity}")
        self.capacity = capacity
        self.obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.action = np.zeros((capacity, act_dim), dtype=np.float32)
        self.reward = np.zeros(capacity, dtype=np.float32)
        self.next_obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.terminated = np.zeros(capacity, dtype=np.float32)
        self.steps = np.ones(capacity, dtype=np.float32)
        self.size = 0
        self.position = 0
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(self, obs: np.ndarray, action: np.ndarray, reward: np.ndarray,
            next_obs: np.ndarray, terminated: np.ndarray, steps: np.ndarray | int = 1) -> None:
        """Append a batch of ``B`` transitions (overwriting the oldest when full).

        Parameters
        ----------
        obs : ndarray, shape (B, obs_dim)
            Observations.
        action : ndarray, shape (B, act_dim)
            Applied gains.
        reward : ndarray, shape (B,)
            Rewards.
        next_obs : ndarray, shape (B, obs_dim)
            Observations after the step.
        terminated : ndarray, shape (B,)
            Whether each episode ended by failure.
        steps : ndarray, shape (B,), or int
            Steps each transition spans (:class:`NStepWindow`; 1 for one-step transitions).
        """
        count = len(reward)
        rows = (self.position + np.arange(count)) % self.capacity
        for name, value in zip(self._FIELDS, (obs, action, reward, next_obs, terminated, steps),
                               strict=True):
            getattr(self, name)[rows] = value
        self.position = int((self.position + count) % self.capacity)
        self.size = min(self.capacity, self.size + count)

    def sample(self, batch_size: int) -> Batch:
        """Draw transitions uniformly with replacement.

        Parameters
        ----------
        batch_size : int
            Number of transitions.

        Returns
        -------
        Batch
            The minibatch.
        """
        if self.size == 0:
            raise ValueError("cannot sample from an empty replay buffer")
        rows = self.rng.integers(0, self.size, size=batch_size)
        return Batch(*(torch.from_numpy(getattr(self, name)[rows]) for name in self._FIELDS))

    def state_dict(self) -> dict[str, Any]:
        """Filled part of the storage, position and RNG state (tensors and plain data)."""
        data: dict[str, Any] = {name: torch.from_numpy(getattr(self, name)[:self.size])
                                for name in self._FIELDS}
        data.update(size=self.size, position=self.position,
                    rng=self.rng.bit_generator.state)
        return data

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`state_dict` returned (capacity and sizes must match).

        Parameters
        ----------
        state : dict
            Output of :meth:`state_dict`.
        """
        size = int(state["size"])
        if size > self.capacity:
            raise ValueError(f"checkpoint holds {size} transitions, capacity is {self.capacity}")
        for name in self._FIELDS:
            if name in state:  # a checkpoint from before n-step transitions holds no steps
                getattr(self, name)[:size] = state[name].numpy()
        self.size, self.position = size, int(state["position"])
        self.rng.bit_generator.state = state["rng"]


class NStepWindow:
    """The last ``n`` vector steps of parallel episodes, released as ``n``-step transitions.

    Every episode of the batch starts and ends at the same vector step (the environment's
    episodes have one length and a round ends at the first termination), so one window serves
    them all. :meth:`push` takes a vector step and returns the transitions that are complete:
    after ``n`` steps the oldest, each spanning ``n`` steps; at the episode's end all those
    held, each spanning the steps left (a failure ends them without bootstrapping).

    Parameters
    ----------
    n : int
        Steps per transition (1: the one-step transitions themselves).
    discount : float
        Discount of the rewards within a transition.
    """

    def __init__(self, n: int, discount: float) -> None:
        if n < 1:
            raise ValueError(f"n-step transitions need n >= 1, got {n}")
        self.n, self.discount = n, discount
        self._held: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def push(self, obs: np.ndarray, action: np.ndarray, reward: np.ndarray,
             next_obs: np.ndarray, terminated: np.ndarray,
             ended: bool) -> list[tuple[np.ndarray, ...]]:
        """Take one vector step; return the complete transitions.

        Parameters
        ----------
        obs, action, reward, next_obs, terminated : ndarray
            The step's one-step transitions, as :meth:`ReplayBuffer.add` takes them.
        ended : bool
            Whether the episodes end with this step (termination or truncation).

        Returns
        -------
        list of tuple
            ``(obs, action, reward, next_obs, terminated, steps)`` per released batch, ready
            for :meth:`ReplayBuffer.add` (oldest first).
        """
        self._held.append((obs, action, np.zeros(len(reward))))
        for k, (_, _, total) in enumerate(self._held):
            total += self.discount ** (len(self._held) - 1 - k) * reward
        if ended:
            released, self._held = self._held, []
        elif len(self._held) == self.n:
            released, self._held = self._held[:1], self._held[1:]
        else:
            return []
        span = len(released) + len(self._held)
        return [(o, a, total, next_obs, terminated, np.full(len(total), span - k, np.float32))
                for k, (o, a, total) in enumerate(released)]
