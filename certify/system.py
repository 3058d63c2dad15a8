"""Linear time-delay systems ``E x' = A0 x + sum_i A_i x(t - tau_i(t))`` and polytopes of them."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["VARIATIONS", "LinearDelaySystem", "PolytopicDelaySystem", "as_polytope"]

Matrix = NDArray[np.float64]

VARIATIONS = ("switching", "frozen")
"""Allowed parameter variations of a :class:`PolytopicDelaySystem`."""

_COND_LIMIT = 1e12


def _frozen_matrix(value: ArrayLike, name: str) -> Matrix:
    """Return ``value`` as a read-only finite square float matrix, or raise ValueError."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real numeric matrix ({exc})") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf entries")
    arr.flags.writeable = False
    return arr


def _solve(e: Matrix, b: Matrix) -> Matrix:
    return np.asarray(np.linalg.solve(e, b), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class LinearDelaySystem:
    """Linear system with several delays, ``E x' = A0 x + sum_i A[i] x(t - tau_i(t))``.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Matrix of the undelayed state (a scalar is read as a 1x1 matrix).
    A : sequence of array_like, each shape (n, n)
        One matrix per delay channel; ``A[i]`` multiplies ``x(t - tau_i(t))``.
    E : array_like, shape (n, n), optional
        Nonsingular descriptor (mass) matrix; ``None`` means the identity.

    Raises
    ------
    ValueError
        On a non-square, mismatched, non-finite or singular matrix, or no delay channel.
    """

    A0: Matrix
    A: tuple[Matrix, ...]
    E: Matrix | None = None

    def __post_init__(self) -> None:
        a0 = _frozen_matrix(self.A0, "A0")
        if isinstance(self.A, np.ndarray) and self.A.ndim == 2:
            raise ValueError("A must be a sequence of delay matrices [A1, ...], not one matrix")
        delayed = tuple(_frozen_matrix(a, f"A[{i}]") for i, a in enumerate(self.A))
        if not delayed:
            raise ValueError("A must hold at least one delay matrix")
        for i, a in enumerate(delayed):
            if a.shape != a0.shape:
                raise ValueError(f"A[{i}] has shape {a.shape}, expected {a0.shape} like A0")
        e = None if self.E is None else _frozen_matrix(self.E, "E")
        if e is not None:
            if e.shape != a0.shape:
                raise ValueError(f"E has shape {e.shape}, expected {a0.shape} like A0")
            if np.linalg.cond(e) > _COND_LIMIT:
                raise ValueError("E is singular or nearly so; descriptor systems need E invertible")
        object.__setattr__(self, "A0", a0)
        object.__setattr__(self, "A", delayed)
        object.__setattr__(self, "E", e)

    @property
    def n(self) -> int:
        """Number of states."""
        return int(self.A0.shape[0])

    @property
    def m(self) -> int:
        """Number of delay channels."""
        return len(self.A)

    @property
    def E_matrix(self) -> Matrix:
        """Descriptor matrix, the identity when ``E`` is ``None``."""
        return np.eye(self.n) if self.E is None else self.E

    def explicit(self) -> tuple[Matrix, tuple[Matrix, ...]]:
        """Return ``(E^-1 A0, (E^-1 A1, ...))``, the explicit form ``x' = ...``.

        Returns
        -------
        tuple
            The undelayed matrix and the tuple of delayed matrices after solving with ``E``.
        """
        if self.E is None:
            return self.A0, self.A
        e = self.E
        return _solve(e, self.A0), tuple(_solve(e, a) for a in self.A)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary (nested lists).

        Returns
        -------
        dict
            Keys ``A0``, ``A`` and ``E`` (``None`` for the identity).
        """
        return {
            "A0": self.A0.tolist(),
            "A": [a.tolist() for a in self.A],
            "E": None if self.E is None else self.E.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LinearDelaySystem:
        """Rebuild a system from :meth:`to_dict` output.

        Parameters
        ----------
        data : dict
            Dictionary with keys ``A0``, ``A`` and optionally ``E``.

        Returns
        -------
        LinearDelaySystem
            The validated system.
        """
        return cls(np.asarray(data["A0"]), tuple(np.asarray(a) for a in data["A"]), data.get("E"))


@dataclass(frozen=True, eq=False)
class PolytopicDelaySystem:
    """Convex hull of linear delay systems with equal state and delay dimensions.

    A certificate for the polytope holds for every convex combination of the vertex
    matrices, including parameters that vary arbitrarily fast inside the hull.

    Parameters
    ----------
    vertices : sequence of LinearDelaySystem
        The vertex systems (at least one).
    variation : {"switching", "frozen"}, optional
        How the parameter may move inside the polytope. ``"switching"`` (default): in any
        way, arbitrarily fast, certified by one common functional. ``"frozen"``: it is
        constant in time (every fixed point of the polytope is certified), which allows a
        parameter-dependent functional (one set of functional matrices per vertex).

    Raises
    ------
    ValueError
        If there is no vertex, the vertices differ in ``n`` or in the number of delays, or
        ``variation`` is unknown.
    """

    vertices: tuple[LinearDelaySystem, ...]
    variation: str = "switching"

    def __post_init__(self) -> None:
        if self.variation not in VARIATIONS:
            raise ValueError(f"variation must be one of {VARIATIONS}, got {self.variation!r}")
        verts = tuple(self.vertices)
        if not verts:
            raise ValueError("a polytope needs at least one vertex")
        for i, v in enumerate(verts):
            if not isinstance(v, LinearDelaySystem):
                raise ValueError(f"vertex {i} is {type(v).__name__}, expected LinearDelaySystem")
            if (v.n, v.m) != (verts[0].n, verts[0].m):
                raise ValueError(
                    f"vertex {i} has n={v.n}, m={v.m}; vertex 0 has n={verts[0].n}, m={verts[0].m}"
                )
        object.__setattr__(self, "vertices", verts)

    @classmethod
    def polytope(
        cls, vertices: Iterable[LinearDelaySystem], variation: str = "switching"
    ) -> PolytopicDelaySystem:
        """Build the polytope spanned by ``vertices``.

        Parameters
        ----------
        vertices : iterable of LinearDelaySystem
            The vertex systems.
        variation : {"switching", "frozen"}, optional
            How the parameter may move inside the polytope (see the class).

        Returns
        -------
        PolytopicDelaySystem
            The polytope.
        """
        return cls(tuple(vertices), variation)

    @property
    def frozen(self) -> bool:
        """Whether the parameter is constant in time (parameter-dependent functional)."""
        return self.variation == "frozen"

    @property
    def n(self) -> int:
        """Number of states."""
        return self.vertices[0].n

    @property
    def m(self) -> int:
        """Number of delay channels."""
        return self.vertices[0].m

    def point(self, weights: Sequence[float]) -> LinearDelaySystem:
        """Return the convex combination of the vertices with the given weights.

        Parameters
        ----------
        weights : sequence of float
            Nonnegative weights, one per vertex, summing to one.

        Returns
        -------
        LinearDelaySystem
            The interior system.
        """
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (len(self.vertices),) or np.any(w < 0) or not np.isclose(w.sum(), 1.0):
            raise ValueError("weights must be nonnegative, one per vertex, and sum to one")
        a0 = sum(wk * v.A0 for wk, v in zip(w, self.vertices, strict=True))
        delayed = [
            sum(wk * v.A[i] for wk, v in zip(w, self.vertices, strict=True)) for i in range(self.m)
        ]
        e = sum(wk * v.E_matrix for wk, v in zip(w, self.vertices, strict=True))
        return LinearDelaySystem(np.asarray(a0), tuple(np.asarray(a) for a in delayed), e)


def as_polytope(system: LinearDelaySystem | PolytopicDelaySystem) -> PolytopicDelaySystem:
    """Return ``system`` as a polytope (a single system becomes a one-vertex polytope).

    Parameters
    ----------
    system : LinearDelaySystem or PolytopicDelaySystem
        The system.

    Returns
    -------
    PolytopicDelaySystem
        The polytope.
    """
    if isinstance(system, PolytopicDelaySystem):
        return system
    if isinstance(system, LinearDelaySystem):
        return PolytopicDelaySystem((system,))
    kind = type(system).__name__
    raise ValueError(f"expected a LinearDelaySystem or PolytopicDelaySystem, got {kind}")
