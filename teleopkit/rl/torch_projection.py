"""The safety layer's projection in torch, so that the actor is trained through it.

The maps are piecewise affine (per-joint polygons) or piecewise rational in the raw action (the
scheduled classes' coupled set), so autograd gives their exact Jacobians almost everywhere:
identity inside the set, the tangent projector on an edge, zero at a vertex. Both take the
observation too: a scheduled class's floor on ``kappa`` follows from the run-time state the
environment appends to it, so the actor is trained through the very set of each step. (A rate
bound, which depends on the previous action, is not in the observation: the environment
enforces it, and the critic sees the applied action.)
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.safety.layer import SafetyLayer

__all__ = ["ScheduledTorchProjection", "TorchProjection", "torch_projection"]


def torch_projection(certified: GainPolytope | ScheduledSet | SafetyLayer) -> nn.Module:
    """The torch projection onto a certified set.

    Parameters
    ----------
    certified : GainPolytope, ScheduledSet or SafetyLayer
        A polytope of per-joint polygons, a scheduled class's set, or a safety layer (its
        :attr:`~teleopkit.safety.layer.SafetyLayer.admissible_set`).

    Returns
    -------
    torch.nn.Module
        :class:`ScheduledTorchProjection` for a scheduled set, else :class:`TorchProjection`.
    """
    if isinstance(certified, SafetyLayer):
        certified = certified.admissible_set
    if isinstance(certified, ScheduledSet):
        return ScheduledTorchProjection(certified)
    return TorchProjection(certified)


class TorchProjection(nn.Module):
    """Exact Euclidean projection onto a per-joint polygon product, differentiable by autograd.

    The same map as :meth:`teleopkit.safety.PolytopeLayer.project_batch` (without a rate bound):
    a point inside its joint's polygon stays, any other goes to the nearest point of the
    polygon's edges.

    Parameters
    ----------
    polytope : GainPolytope
        The certified set (bounded, non-empty, no row coupling two joints).
    """

    def __init__(self, polytope: GainPolytope) -> None:
        super().__init__()
        n = polytope.dimension // 2
        polygons = [polytope.joint_vertices(i) for i in range(n)]
        if any(len(p) == 0 for p in polygons):
            raise ValueError("the gain polytope is empty")
        k = max(len(p) for p in polygons)
        # Pad each polygon by repeating its first vertex: the extra edges have length zero and
        # their nearest point is that vertex, already a candidate.
        vertices = np.stack([np.concatenate([p, np.repeat(p[:1], k - len(p), axis=0)])
                             for p in polygons])
        edges = np.roll(vertices, -1, axis=1) - vertices
        length2 = np.maximum(np.sum(edges**2, axis=-1), 1e-300)
        g = polytope.G
        owner = np.stack([(g[:, i] != 0) | (g[:, n + i] != 0) for i in range(n)], axis=1)
        self.n = n
        self._constants = {dtype: tuple(torch.as_tensor(x, dtype=dtype) for x in
                                        (vertices, edges, length2, g.T, polytope.h, owner))
                           for dtype in (torch.float32, torch.float64)}

    def forward(self, action: torch.Tensor, obs: torch.Tensor | None = None) -> torch.Tensor:
        """Project actions onto the certified polytope.

        Parameters
        ----------
        action : torch.Tensor, shape (B, 2 n)
            Raw gains (float32 or float64).
        obs : torch.Tensor, optional
            Unused: the polytope is the same at every step.

        Returns
        -------
        torch.Tensor, shape (B, 2 n)
            Projected gains, in the dtype of ``action``.
        """
        start, edge, length2, g_t, h, owner = self._constants[action.dtype]
        n = self.n
        points = torch.stack([action[:, :n], action[:, n:]], dim=-1)  # (B, n, 2)
        rel = points[:, :, None, :] - start  # (B, n, k, 2)
        t = ((rel * edge).sum(-1) / length2).clamp(0.0, 1.0)
        gap = rel - t[..., None] * edge  # point minus its nearest point on each edge
        best = (gap * gap).sum(-1).argmin(-1, keepdim=True)  # (B, n, 1)
        shift = torch.gather(gap, 2, best[..., None].expand(-1, -1, 1, 2)).squeeze(2)
        outside = (action @ g_t > h).to(action.dtype) @ owner > 0  # (B, n)
        projected = points - outside[..., None] * shift
        return torch.cat([projected[..., 0], projected[..., 1]], dim=-1)


class ScheduledTorchProjection(nn.Module):
    """Exact projection onto the static set of a scheduled class, differentiable by autograd.

    The same map as :class:`~teleopkit.safety.schedule.ScheduleLayer` without the run-time floor:
    the stiffness ``K_r = kappa s`` minimises the cost with the best damping (the sorted kinks
    of :mod:`teleopkit.safety.schedule`), then every gain is clipped into its bounds.

    Parameters
    ----------
    scheduled : ScheduledSet
        The class's set: common shape, cone ``B_r^i >= rho_i s_i kappa + beta_i``, damping box
        and ``kappa`` range; its rule (budget or tank) says how the observation's last columns
        (level, previous ``kappa``, remote energy) give the step's floor.
    """

    def __init__(self, scheduled: ScheduledSet) -> None:
        super().__init__()
        self.n = scheduled.n_joints
        self.kappa_lo, self.kappa_hi = scheduled.kappa_low, scheduled.kappa_high
        self.tank = scheduled.rule == "tank"
        self._constants = {dtype: tuple(torch.as_tensor(x, dtype=dtype)
                                        for x in scheduled.arrays())
                           for dtype in (torch.float32, torch.float64)}

    def floor(self, obs: torch.Tensor | None) -> torch.Tensor | float:
        """The step's floor on ``kappa`` from the observation's run-time columns.

        Parameters
        ----------
        obs : torch.Tensor, shape (B, obs_dim), optional
            Observations ending with the level, the previous ``kappa`` and, with a tank, the
            remote energy (:meth:`~teleopkit.safety.schedule.ScheduleLayer.run_time_state`).

        Returns
        -------
        torch.Tensor, shape (B, 1), or float
            The floor (``kappa_lo`` without an observation: the static set).
        """
        if obs is None:
            return self.kappa_lo
        tank = self.tank
        level, previous = obs[:, -3 if tank else -2], obs[:, -2 if tank else -1]
        if tank:
            energy = obs[:, -1]
            floor = previous * energy / (energy + previous * level).clamp(min=1e-300)
        else:
            floor = previous * torch.exp(-level)
        return torch.minimum(floor.clamp(min=self.kappa_lo), previous)[:, None]

    def forward(self, action: torch.Tensor, obs: torch.Tensor | None = None) -> torch.Tensor:
        """Project actions onto the set of their step.

        Parameters
        ----------
        action : torch.Tensor, shape (B, 2 n)
            Raw gains (float32 or float64).
        obs : torch.Tensor, shape (B, obs_dim), optional
            The observations the actions answer (for the floor); the static set without.

        Returns
        -------
        torch.Tensor, shape (B, 2 n)
            Projected gains, in the dtype of ``action``.
        """
        shape, rho, beta, b_lo, b_hi = self._constants[action.dtype]
        n = self.n
        k_raw, b_raw = action[:, :n], action[:, n:]
        slope = rho * shape
        kinks, order = torch.sort((torch.maximum(b_raw, b_lo) - beta) / slope, dim=1)
        gain = torch.gather(slope * (b_raw - beta), 1, order)
        square = torch.gather((slope * slope).expand_as(b_raw), 1, order)
        zero = torch.zeros_like(kinks[:, :1])
        num = (k_raw * shape).sum(1, keepdim=True) + torch.cat([zero, gain.cumsum(1)], 1)
        den = (shape * shape).sum() + torch.cat([zero, square.cumsum(1)], 1)
        roots = num / den  # minimiser of each piece, pieces between consecutive kinks
        ends = torch.cat([kinks, torch.full_like(zero, torch.inf)], 1)
        starts = torch.cat([torch.full_like(zero, -torch.inf), kinks], 1)
        first = (roots <= ends).to(torch.int8).argmax(1, keepdim=True)
        kappa = torch.maximum(roots.gather(1, first), starts.gather(1, first))
        floor = torch.as_tensor(self.floor(obs), dtype=action.dtype)
        kappa = torch.clamp(torch.maximum(kappa, floor), max=self.kappa_hi)
        cone = slope * kappa + beta
        damping = torch.minimum(torch.maximum(b_raw, torch.maximum(b_lo, cone)), b_hi)
        return torch.cat([kappa * shape, damping], dim=1)
