"""Replay storage of the TD3 learner: preallocated numpy arrays with seeded sampling."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch

__all__ = ["Batch", "ReplayBuffer"]


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
    """

    obs: torch.Tensor
    action: torch.Tensor
    reward: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor


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

    _FIELDS = ("obs", "action", "reward", "next_obs", "terminated")

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
        self.size = 0
        self.position = 0
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(self, obs: np.ndarray, action: np.ndarray, reward: np.ndarray,
            next_obs: np.ndarray, terminated: np.ndarray) -> None:
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
        """
        count = len(reward)
        rows = (self.position + np.arange(count)) % self.capacity
        for name, value in zip(self._FIELDS, (obs, action, reward, next_obs, terminated),
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
            getattr(self, name)[:size] = state[name].numpy()
        self.size, self.position = size, int(state["position"])
        self.rng.bit_generator.state = state["rng"]
