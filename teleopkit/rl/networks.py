"""The tuner's networks: an actor whose output map covers the action box, and a critic.

The actor maps observations to raw gains through one of two output maps
(:data:`~teleopkit.rl.policy.OUTPUT_MAPS`): the paper's ``low + (start - low) softplus(z) / ln 2``
(``z = 0`` gives ``start``, by default the centre of the action box; unbounded above), or
``low + (high - low) (1 + tanh(z)) / 2`` (the box and nothing else, as Stable-Baselines3's TD3
squashes its actions). The critic has a state path and an action path merged into a scalar (the
paper's), or one path that takes both at its input. Both standardise their inputs with fixed
statistics, and every weight is drawn from a generator the caller owns (the global RNG is never
touched).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from teleopkit.rl.policy import check_output_map

__all__ = ["Actor", "Critic", "Standardise", "half_range", "inside_box"]

_LN2 = math.log(2.0)


def _mlp(sizes: tuple[int, ...], generator: torch.Generator) -> list[nn.Module]:
    """Linear layers of the given widths with ReLU between them (none after the last)."""
    layers: list[nn.Module] = []
    for i, (fan_in, fan_out) in enumerate(itertools.pairwise(sizes)):
        layers.append(_linear(fan_in, fan_out, generator))
        if i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return layers


def _linear(fan_in: int, fan_out: int, generator: torch.Generator,
            bound: float | None = None) -> nn.Linear:
    """A linear layer initialised from ``generator``: PyTorch's default, or ``U(-bound, bound)``.

    PyTorch's own initialisation draws from the global RNG; this one is seeded by the agent
    (and the global RNG is left alone: the layer is built uninitialised).
    """
    layer = nn.utils.skip_init(nn.Linear, fan_in, fan_out)
    limit = 1.0 / math.sqrt(fan_in) if bound is None else bound
    with torch.no_grad():
        layer.weight.uniform_(-limit, limit, generator=generator)
        layer.bias.uniform_(-limit, limit, generator=generator)
    return layer


class Standardise(nn.Module):
    """Fixed affine input map ``(x - mean) / std`` (buffers: saved, never trained).

    Parameters
    ----------
    dim : int
        Input size; the statistics start at mean 0 and standard deviation 1.
    """

    mean: torch.Tensor
    std: torch.Tensor

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Standardise ``x``.

        Parameters
        ----------
        x : torch.Tensor, shape (B, dim)
            Inputs.

        Returns
        -------
        torch.Tensor, shape (B, dim)
            ``(x - mean) / std``.
        """
        return (x - self.mean) / self.std


class Actor(nn.Module):
    """Deterministic policy ``obs -> raw gains``: ``obs_dim``-128-64-``act_dim`` and an output map.

    Parameters
    ----------
    obs_dim : int
        Observation size (14 for two joints).
    low, high : ndarray, shape (act_dim,)
        The action box the output must cover (see the module notes for the maps).
    generator : torch.Generator
        Source of the initial weights.
    hidden : tuple of int
        Hidden widths.
    start : ndarray, shape (act_dim,), optional
        The gains at ``z = 0``, where the untrained actor starts (default the centre of the
        box). Softplus map: strictly above ``low``, the map becomes ``low + (start - low)
        softplus(z) / ln 2``, which still reaches every gain of the box. Tanh map: strictly
        inside the box, the last layer's bias is offset by ``artanh((start - centre) /
        ((high - low) / 2))``. A gain whose range is a single value (``low == high``, for example a
        stiffness held constant) is that value.
    output : {"softplus", "tanh"}
        The output map (:data:`~teleopkit.rl.policy.OUTPUT_MAPS`). The softplus map's last
        layer starts small (``U(-3e-3, 3e-3)``, DDPG's), every output near ``start``; the tanh
        map's last layer has PyTorch's default initialisation, the outputs spread over the box
        from the start.
    """

    low: torch.Tensor
    span: torch.Tensor

    def __init__(self, obs_dim: int, low: np.ndarray, high: np.ndarray,
                 generator: torch.Generator, hidden: tuple[int, ...] = (128, 64),
                 start: np.ndarray | None = None, output: str = "softplus") -> None:
        super().__init__()
        check_output_map(output)
        self.output = output
        act_dim = len(low)
        self.normalise = Standardise(obs_dim)
        body = _mlp((obs_dim, *hidden), generator)
        self.body = nn.Sequential(*body, nn.ReLU())
        self.head = _linear(hidden[-1], act_dim, generator,
                            bound=3e-3 if output == "softplus" else None)
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        start = (low + high) / 2 if start is None else np.asarray(start, dtype=float)
        fixed = high == low
        inside = (start > low) & ((start < high) | (output == "softplus"))
        if start.shape != low.shape or not np.all(inside | fixed):
            where = "above the box's lower corner" if output == "softplus" else "inside the box"
            raise ValueError(f"the actor's start {start.tolist()} must lie {where} "
                             f"{low.tolist()} .. {high.tolist()}")
        start = np.where(fixed, low, start)
        if output == "softplus":
            span = (start - low) / _LN2
        else:
            span = (high - low) / 2
            shift = np.arctanh((start - (low + high) / 2) / half_range(low, high))
            with torch.no_grad():
                self.head.bias.add_(torch.as_tensor(shift, dtype=torch.float32))
        self.register_buffer("low", torch.as_tensor(low, dtype=torch.float32))
        self.register_buffer("span", torch.as_tensor(span, dtype=torch.float32))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Raw gains ``low + span f(z)``, ``f`` the output map, shape ``(B, act_dim)``.

        Parameters
        ----------
        obs : torch.Tensor, shape (B, obs_dim)
            Observations.

        Returns
        -------
        torch.Tensor, shape (B, act_dim)
            Raw (unprojected) gains.
        """
        z = self.head(self.body(self.normalise(obs)))
        mapped = F.softplus(z) if self.output == "softplus" else 1.0 + torch.tanh(z)
        return self.low + self.span * mapped


def half_range(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Half the box's range per gain (1 for a gain with a single value: nothing to rescale).

    Parameters
    ----------
    low, high : ndarray, shape (act_dim,)
        The action box.

    Returns
    -------
    ndarray, shape (act_dim,)
        ``(high - low) / 2`` where positive, else 1.
    """
    half = (np.asarray(high, dtype=float) - np.asarray(low, dtype=float)) / 2
    return np.where(half > 0, half, 1.0)


def inside_box(gains: np.ndarray, low: np.ndarray, high: np.ndarray,
               margin: float = 0.01) -> np.ndarray:
    """``gains`` moved at least ``margin`` of the box's range inside it.

    A start an output map can take: tanh and softplus reach the edges only in the limit.

    Parameters
    ----------
    gains : ndarray, shape (act_dim,)
        Gains in or on the box.
    low, high : ndarray, shape (act_dim,)
        The action box.
    margin : float
        Fraction of each gain's range.

    Returns
    -------
    ndarray, shape (act_dim,)
        The gains clipped to ``[low + margin (high - low), high - margin (high - low)]``.
    """
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    inset = margin * (high - low)
    return np.clip(gains, low + inset, high - inset)


class Critic(nn.Module):
    """Q-network: a state path (128-64) and an action path (64) concatenated into 60-36-1.

    Parameters
    ----------
    obs_dim : int
        Observation size.
    low, high : ndarray, shape (act_dim,)
        Action box; actions are rescaled to ``[-1, 1]`` over it on input.
    generator : torch.Generator
        Source of the initial weights.
    hidden_state, hidden_action, hidden_merged : tuple of int
        Widths of the state path, the action path and the merged layers (before the scalar
        output). An empty ``hidden_action`` joins the paths: the rescaled action is
        concatenated with the standardised observation at the state path's input (as
        Stable-Baselines3's and the TD3 authors' critics take them).
    """

    centre: torch.Tensor
    half_span: torch.Tensor

    def __init__(self, obs_dim: int, low: np.ndarray, high: np.ndarray,
                 generator: torch.Generator, hidden_state: tuple[int, ...] = (128, 64),
                 hidden_action: tuple[int, ...] = (64,),
                 hidden_merged: tuple[int, ...] = (60, 36)) -> None:
        super().__init__()
        self.normalise = Standardise(obs_dim)
        self.register_buffer("centre", torch.as_tensor((high + low) / 2, dtype=torch.float32))
        self.register_buffer("half_span", torch.as_tensor(half_range(low, high),
                                                          dtype=torch.float32))
        joined = not hidden_action
        state_in = obs_dim + len(low) if joined else obs_dim
        self.state_path = nn.Sequential(*_mlp((state_in, *hidden_state), generator))
        self.action_path = (None if joined else
                            nn.Sequential(*_mlp((len(low), *hidden_action), generator)))
        merged_in = hidden_state[-1] + (0 if joined else hidden_action[-1])
        self.merged = nn.Sequential(nn.ReLU(),
                                    *_mlp((merged_in, *hidden_merged, 1), generator))

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """``Q(obs, action)``, shape ``(B,)``.

        Parameters
        ----------
        obs : torch.Tensor, shape (B, obs_dim)
            Observations.
        action : torch.Tensor, shape (B, act_dim)
            Gains.

        Returns
        -------
        torch.Tensor, shape (B,)
            Action values.
        """
        scaled = (action - self.centre) / self.half_span
        if self.action_path is None:
            features = self.state_path(torch.cat([self.normalise(obs), scaled], dim=-1))
        else:
            features = torch.cat([self.state_path(self.normalise(obs)),
                                  self.action_path(scaled)], dim=-1)
        return self.merged(features).squeeze(-1)
