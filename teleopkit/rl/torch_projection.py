"""The safety layer's projection in torch, so that the actor is trained through it.

The map is piecewise affine, so autograd gives its exact Jacobian: identity inside the set, the
tangent projector on an edge, zero at a vertex.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from teleopkit.certification.gain_sets import GainPolytope

__all__ = ["TorchProjection"]


class TorchProjection(nn.Module):
    """Exact Euclidean projection onto a per-joint polygon product, differentiable by autograd.

    The same map as :meth:`teleopkit.safety.SafetyLayer.project_batch` (without a rate bound):
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

    def forward(self, action: torch.Tensor) -> torch.Tensor:
        """Project actions onto the certified polytope.

        Parameters
        ----------
        action : torch.Tensor, shape (B, 2 n)
            Raw gains (float32 or float64).

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
