"""Delay channels: the part of the state that each delay actually acts on.

Delay ``i`` enters the dynamics only through ``A_i x(t - tau_i)``. With ``C_i`` an
orthonormal basis of the row space of ``A_i`` over all corners of a polytope,
``A_i = B_i C_i`` with ``B_i = A_i C_i^T`` at every corner (and, by linearity, at every
point of the polytope), so the dynamics only need the delayed signal ``y_i = C_i x`` of
dimension ``r_i = rank``. For a teleoperator, where only positions are transmitted, this
shrinks the LMIs several-fold; for full-rank ``A_i``, ``C_i = I`` and nothing changes.

What the reduction keeps and what it loses: the dynamics are represented exactly, but a
functional built on ``y_i`` (integral terms ``int y_i^T Q_i y_i`` and so on) is the special
case ``Q = C_i^T Q_i C_i`` of the functional built on the whole state. The reduced LMIs are
therefore sound, and can be more conservative: on a 2x2 benchmark with a rank-one delay matrix
they certify the same bound for fast-varying delays but up to 5 % less with a derivative bound
(Wirtinger, ``mu = 0.1``); on a one-joint teleoperator the loss is 3-5 % even for fast-varying
delays. :data:`MODES` names both forms; the public entry points try both
where they differ and keep the better.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.uncertainty import Direction

__all__ = ["MODES", "Channels"]

MODES = ("reduced", "full")
"""Channel forms: ``y_i = C_i x`` on the row space of ``A_i``, or the whole state (``C_i = I``)."""

_RANK_RTOL = 1e-10
_BASIS_TOL = 1e-10


@dataclass(frozen=True, eq=False)
class Channels:
    """Output maps ``y_i = C[i] x`` of the delay channels.

    Parameters
    ----------
    n : int
        Number of states.
    C : tuple of numpy.ndarray
        One ``(r_i, n)`` matrix with orthonormal rows per delay.
    """

    n: int
    C: tuple[NDArray[np.float64], ...]

    @classmethod
    def of(cls, system: PolytopicDelaySystem, mode: str = "reduced") -> Channels:
        """Row-space bases of the delay matrices over all vertices.

        Parameters
        ----------
        system : PolytopicDelaySystem
            The system.
        mode : str, optional
            ``"reduced"`` (row spaces) or ``"full"`` (every ``C_i = I``).

        Returns
        -------
        Channels
            ``C_i = I`` where ``A_i`` has full rank at some vertex combination (or for
            ``"full"``), otherwise an orthonormal basis of the joint row space (at least one
            row).
        """
        if mode not in MODES:
            raise ValueError(f"channels must be one of {', '.join(MODES)}, got {mode!r}")
        if mode == "full":
            return cls(system.n, tuple(np.eye(system.n) for _ in range(system.m)))
        maps = []
        for i in range(system.m):
            stacked = np.vstack([v.A[i] for v in system.corners()])
            _, sing, vt = np.linalg.svd(stacked)
            rank = max(1, int(np.sum(sing > _RANK_RTOL * max(sing[0], 1e-300))))
            maps.append(np.eye(system.n) if rank == system.n else vt[:rank].copy())
        return cls(system.n, tuple(maps))

    @property
    def reduced(self) -> bool:
        """Whether some channel acts on less than the whole state."""
        return any(r < self.n for r in self.r)

    @property
    def m(self) -> int:
        """Number of delays."""
        return len(self.C)

    @property
    def r(self) -> tuple[int, ...]:
        """Dimension of each delayed signal."""
        return tuple(int(c.shape[0]) for c in self.C)

    def coef(self, i: int) -> Any:
        """``C_i`` as a form coefficient (the scalar 1 when ``C_i`` is the identity).

        Parameters
        ----------
        i : int
            Delay index.

        Returns
        -------
        float or numpy.ndarray
            Coefficient mapping ``x`` to ``y_i``.
        """
        c = self.C[i]
        return 1.0 if c.shape[0] == self.n and np.array_equal(c, np.eye(self.n)) else c

    def input_matrix(self, vertex: LinearDelaySystem | Direction, i: int) -> Any:
        """``B_i = A_i C_i^T`` of one vertex (``A_i`` itself when ``C_i = I``).

        Parameters
        ----------
        vertex : LinearDelaySystem or Direction
            A vertex of the system (or a parameter direction).
        i : int
            Delay index.

        Returns
        -------
        numpy.ndarray
            The ``(n, r_i)`` input matrix of delay ``i``.
        """
        coef = self.coef(i)
        return vertex.A[i] if np.ndim(coef) == 0 else vertex.A[i] @ self.C[i].T

    def valid_for(self, system: PolytopicDelaySystem) -> bool:
        """Whether every ``C_i`` has orthonormal rows and ``A_i = A_i C_i^T C_i`` at all vertices.

        Parameters
        ----------
        system : PolytopicDelaySystem
            The system.

        Returns
        -------
        bool
            ``True`` if the channel maps represent the system exactly (to ``1e-10``).
        """
        if self.m != system.m or self.n != system.n:
            return False
        for i, c in enumerate(self.C):
            if c.ndim != 2 or c.shape[1] != self.n or not np.all(np.isfinite(c)):
                return False
            if not np.allclose(c @ c.T, np.eye(c.shape[0]), rtol=0.0, atol=_BASIS_TOL):
                return False
            for v in system.corners():
                scale = max(1.0, float(np.abs(v.A[i]).max()))
                if np.abs(v.A[i] - v.A[i] @ c.T @ c).max() > _BASIS_TOL * scale:
                    return False
        return True
