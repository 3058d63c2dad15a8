"""Linear time-delay systems ``E x' = A0 x + sum_i A_i x(t - tau_i(t))`` and polytopes of them."""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import matrix_balance

from certify.arrays import as_float, freeze_finite
from certify.uncertainty import AffineUncertainty, Direction

__all__ = ["VARIATIONS", "LinearDelaySystem", "PolytopicDelaySystem", "as_polytope"]

Matrix = NDArray[np.float64]

VARIATIONS = ("switching", "frozen")
"""Allowed parameter variations of a :class:`PolytopicDelaySystem`."""

_COND_LIMIT = 1e12


def _frozen_matrix(value: ArrayLike, name: str) -> Matrix:
    """Return ``value`` as a read-only finite square float matrix, or raise ValueError."""
    arr = as_float(value, name, "matrix")
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {arr.shape}")
    return freeze_finite(arr, name)


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

    def shifted(self, uncertainty: AffineUncertainty, theta: ArrayLike) -> LinearDelaySystem:
        """Move the system along the directions of ``uncertainty`` by ``theta``.

        Parameters
        ----------
        uncertainty : AffineUncertainty
            The parameter directions.
        theta : array_like, shape (p,)
            Parameter values.

        Returns
        -------
        LinearDelaySystem
            ``(E, A0, A_i) + sum_k theta_k D_k``.
        """
        values = np.asarray(theta, dtype=np.float64)
        dirs = uncertainty.directions
        e = self.E_matrix + sum(t * d.E_matrix for t, d in zip(values, dirs, strict=True))
        a0 = self.A0 + sum(t * d.A0 for t, d in zip(values, dirs, strict=True))
        delayed = tuple(a + sum(t * d.A[i] for t, d in zip(values, dirs, strict=True))
                        for i, a in enumerate(self.A))
        return LinearDelaySystem(a0, delayed, e)

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
    uncertainty : AffineUncertainty, optional
        Further parameters ``theta`` entering affinely, ``vertex + sum_k theta_k D_k``
        (the vertices are the systems at ``theta = 0``), anywhere in the hull of the
        uncertainty's points, varying arbitrarily fast whatever ``variation`` says or as fast
        as the uncertainty's ``rates`` allow. They are certified by multipliers
        (:mod:`certify.uncertainty`) instead of enumerating their vertices; :meth:`corners`
        lists the systems this covers.

    Raises
    ------
    ValueError
        If there is no vertex, the vertices differ in ``n`` or in the number of delays,
        ``variation`` is unknown, or the uncertainty does not match the vertices.
    """

    vertices: tuple[LinearDelaySystem, ...]
    variation: str = "switching"
    uncertainty: AffineUncertainty | None = None

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
        if self.uncertainty is not None:
            d = self.uncertainty.directions[0]
            if d.A0.shape != (self.n, self.n) or len(d.A) != self.m:
                raise ValueError(
                    f"the uncertainty's directions have n={d.A0.shape[0]}, m={len(d.A)}; "
                    f"the vertices have n={self.n}, m={self.m}")
            self.corners()  # every corner must be a valid system (nonsingular E)

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

    def nominal(self, vertex: LinearDelaySystem) -> LinearDelaySystem:
        """A vertex at the centre of the uncertainty (the vertex itself without one).

        Parameters
        ----------
        vertex : LinearDelaySystem
            One of :attr:`vertices`.

        Returns
        -------
        LinearDelaySystem
            The system the multiplier conditions are centred on.
        """
        if self.uncertainty is None:
            return vertex
        return vertex.shifted(self.uncertainty, self.uncertainty.center)

    def scaled(self, scaling: ArrayLike) -> PolytopicDelaySystem:
        """The same polytope in the coordinates ``z`` of ``x = diag(scaling) z``.

        Every matrix ``X`` (``E``, ``A0``, ``A_i`` and the uncertainty's directions) becomes
        ``D^-1 X D``: the rows are scaled like the states, so the polytope's stability and
        certificates are unchanged, only their numerical conditioning.

        Parameters
        ----------
        scaling : array_like, shape (n,)
            Positive state scales.

        Returns
        -------
        PolytopicDelaySystem
            The scaled polytope (same variation and uncertainty points).
        """
        d = np.asarray(scaling, dtype=np.float64)
        if d.shape != (self.n,) or not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise ValueError(f"scaling must hold {self.n} positive finite numbers")

        def similar(x: Matrix) -> Matrix:
            return np.asarray(x * d[None, :] / d[:, None])

        vertices = tuple(LinearDelaySystem(similar(v.A0), tuple(similar(a) for a in v.A),
                                           similar(v.E_matrix)) for v in self.vertices)
        unc = self.uncertainty
        if unc is not None:
            dirs = tuple(Direction(similar(k.A0), tuple(similar(a) for a in k.A),
                                   similar(k.E_matrix)) for k in unc.directions)
            unc = AffineUncertainty(dirs, unc.points, unc.names, unc.rates)
        return PolytopicDelaySystem(vertices, self.variation, unc)

    def balancing(self) -> Matrix:
        """Power-of-two state scales that balance the magnitudes of the explicit dynamics.

        ``scipy.linalg.matrix_balance`` of the sum over all corners of ``|E^-1 A0|`` and
        ``|E^-1 A_i|``. Powers of two keep :meth:`scaled` exact in floating point.

        Returns
        -------
        numpy.ndarray, shape (n,)
            The scales.
        """
        total = np.zeros((self.n, self.n))
        for corner in self.corners():
            a0, delayed = corner.explicit()
            total += np.abs(a0) + sum(np.abs(a) for a in delayed)
        _, (scale, _) = matrix_balance(total, permute=False, separate=True)
        return np.asarray(scale, dtype=np.float64)

    def corners(self) -> list[LinearDelaySystem]:
        """Every vertex at every point of the uncertainty (the vertices without one).

        Returns
        -------
        list of LinearDelaySystem
            The systems whose hull the certificate covers, vertex-major.
        """
        return list(self._corners)

    @functools.cached_property
    def _corners(self) -> tuple[LinearDelaySystem, ...]:
        """:meth:`corners`, built once (the channels, data and balancing all read them)."""
        if self.uncertainty is None:
            return self.vertices
        points = self.uncertainty.points
        return tuple(v.shifted(self.uncertainty, theta) for v in self.vertices for theta in points)

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
