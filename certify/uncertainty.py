"""Affine parameters varying arbitrarily fast, certified by full-block multipliers.

A polytope of ``V`` systems costs one LMI per vertex, and a box of ``p`` parameters has
``2^p`` vertices: a two-joint teleoperator with two gains per joint already gives 16 LMIs
per configuration, too many for an interior-point solver. When the parameters enter the
matrices affinely and with low rank (a gain multiplies one row of the dynamics), the
full-block S-procedure (Scherer 2001) avoids the enumeration.

The system is ``E(theta) x' = A0(theta) x + sum_i A_i(theta) x(t - tau_i)`` with
``(E, A0, A_i)(theta) = vertex + sum_k theta_k D_k``, ``D_k`` the *direction* of parameter
``k`` and ``theta(t)`` anywhere in the convex hull of the given points, changing in any way.
In the descriptor/Finsler form of :mod:`certify.conditions` each derivative condition reads
``M0 + He(U Delta V^T) < 0`` where ``Delta = diag(delta_k I_{r_k})`` holds the normalised
deviations of ``theta`` from the centre of the points, ``U = N G`` is affine in the Finsler
slack ``N`` and ``V = H`` is constant, with ``sum_k delta_k Gamma_k = G Delta H^T`` a rank
factorisation of the parameter part of the descriptor relation ``Gamma``. It holds for
every ``Delta`` in the hull if a multiplier ``(Q, S, R)`` satisfies

``[[M0 + V R V^T, U + V S^T], [U^T + S V^T, Q]] < 0`` and
``R + S^T Delta + Delta S + Delta Q Delta >= 0`` at every point ``Delta``:

``Q < 0`` makes the second condition concave in ``Delta``, so it holds on the whole hull,
and substituting ``w = Delta V^T xi`` in the first one gives the derivative condition.
The LMI grows by ``sum_k r_k`` rows instead of being repeated at every parameter vertex.
Because one functional serves every ``theta``, the certificate covers arbitrarily fast
parameter variation (hence also constant parameters, more conservatively than a
parameter-dependent functional would).

A parameter may instead have a bounded rate, ``|theta_k'(t)| <= rho_k`` (``rho_k = 0``: a
constant parameter). The storage term of the functional then depends on it:
``x^T (P + sum_k delta_k dP_k) x`` over the parameters with finite rates. Its derivative adds
``2 x^T (sum_k delta_k dP_k) x'``, one more term ``He(U_P Delta_P V_P^T)`` of the same form
(``U_P = [dP_1 ... dP_q]`` on the rows of ``x``, ``V_P`` the columns of ``x'``,
``Delta_P = diag(delta_k I_n)``), handled by the same multiplier, and
``x^T (sum_k delta_k' dP_k) x <= x^T (sum_k (rho_k / r_k) Z_k) x`` with ``Z_k >= +-dP_k``
(``r_k`` the radius of parameter ``k``). The storage must be positive at every point. This is
the gain-dependent functional with a rate bound: between one common functional (arbitrary
switching) and one functional per constant parameter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from certify.arrays import as_float, freeze_finite
from certify.blocks import BlockMatrix, MatrixInequality, diag, hadamard

__all__ = ["AffineUncertainty", "Direction", "factor", "robust_conditions"]

Matrix = NDArray[np.float64]

_RANK_RTOL = 1e-12


def _finite_matrix(value: ArrayLike, shape: tuple[int, ...], name: str) -> Matrix:
    """Return ``value`` as a read-only finite float array of ``shape``, or raise ValueError."""
    arr = as_float(value, name)
    if arr.shape != shape:
        raise ValueError(f"{name} has shape {arr.shape}, expected {shape}")
    return freeze_finite(arr, name)


@dataclass(frozen=True, eq=False)
class Direction:
    """Change of ``(E, A0, A_i)`` per unit of one parameter.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Change of the undelayed matrix.
    A : sequence of array_like, each shape (n, n)
        Change of each delay matrix.
    E : array_like, shape (n, n), optional
        Change of the descriptor matrix (``None``: zero).

    Raises
    ------
    ValueError
        On mismatched shapes or non-finite entries.
    """

    A0: Matrix
    A: tuple[Matrix, ...]
    E: Matrix | None = None

    def __post_init__(self) -> None:
        a0 = np.asarray(self.A0, dtype=np.float64)
        if a0.ndim != 2 or a0.shape[0] != a0.shape[1]:
            raise ValueError(f"a direction's A0 must be square, got shape {a0.shape}")
        shape = a0.shape
        object.__setattr__(self, "A0", _finite_matrix(a0, shape, "direction A0"))
        delayed = tuple(_finite_matrix(a, shape, f"direction A[{i}]")
                        for i, a in enumerate(self.A))
        object.__setattr__(self, "A", delayed)
        e = np.zeros(shape) if self.E is None else self.E
        object.__setattr__(self, "E", _finite_matrix(e, shape, "direction E"))

    @property
    def E_matrix(self) -> Matrix:
        """Change of the descriptor matrix (zero when not given)."""
        assert self.E is not None
        return self.E

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary.

        Returns
        -------
        dict
            Keys ``A0``, ``A`` and ``E``.
        """
        return {"A0": self.A0.tolist(), "A": [a.tolist() for a in self.A],
                "E": self.E_matrix.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Direction:
        """Rebuild a direction from :meth:`to_dict` output.

        Parameters
        ----------
        data : dict
            Dictionary with keys ``A0``, ``A`` and optionally ``E``.

        Returns
        -------
        Direction
            The validated direction.
        """
        return cls(np.asarray(data["A0"]), tuple(np.asarray(a) for a in data["A"]), data.get("E"))


@dataclass(frozen=True, eq=False)
class AffineUncertainty:
    """Parameters ``theta`` entering a system affinely, anywhere in the hull of ``points``.

    Parameters
    ----------
    directions : sequence of Direction
        One direction per parameter.
    points : array_like, shape (v, p)
        Points whose convex hull contains every value of ``theta`` (for example the
        vertices of a box or of a product of polygons).
    names : sequence of str, optional
        Parameter names (for messages); default ``theta0, theta1, ...``.
    rates : array_like, shape (p,), optional
        Bound on ``|theta_k'(t)|`` per parameter, in parameter units per unit time: ``inf``
        (the default) for arbitrarily fast variation, ``0`` for a constant parameter. A finite
        rate makes the storage depend on the parameter (see the module docstring).

    Raises
    ------
    ValueError
        On no direction, mismatched shapes, non-finite points, names of the wrong length, or
        negative or NaN rates.
    """

    directions: tuple[Direction, ...]
    points: Matrix
    names: tuple[str, ...] = ()
    rates: Matrix | None = None

    def __post_init__(self) -> None:
        dirs = tuple(self.directions)
        if not dirs:
            raise ValueError("an uncertainty needs at least one parameter direction")
        for i, d in enumerate(dirs):
            if not isinstance(d, Direction):
                raise ValueError(f"direction {i} is {type(d).__name__}, expected Direction")
            if (d.A0.shape, len(d.A)) != (dirs[0].A0.shape, len(dirs[0].A)):
                raise ValueError(f"direction {i} does not match the shape of direction 0")
        points = np.atleast_2d(np.asarray(self.points, dtype=np.float64))
        if points.ndim != 2 or points.shape[1] != len(dirs) or points.shape[0] == 0:
            raise ValueError(f"points must have shape (v, {len(dirs)}), got {points.shape}")
        points = _finite_matrix(points, points.shape, "points")
        names = tuple(self.names) or tuple(f"theta{k}" for k in range(len(dirs)))
        if len(names) != len(dirs):
            raise ValueError(f"{len(names)} names for {len(dirs)} parameters")
        rates = as_float(np.inf if self.rates is None else self.rates, "rates")
        rates = np.broadcast_to(rates, (len(dirs),)).copy() if rates.ndim == 0 else rates
        if rates.shape != (len(dirs),) or np.any(np.isnan(rates)) or np.any(rates < 0):
            raise ValueError(f"rates must hold {len(dirs)} non-negative numbers (inf for "
                             f"arbitrary variation), got {rates.tolist()}")
        rates.flags.writeable = False
        object.__setattr__(self, "directions", dirs)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "rates", rates)

    @property
    def p(self) -> int:
        """Number of parameters."""
        return len(self.directions)

    @property
    def center(self) -> Matrix:
        """Centre of the bounding box of the points (the nominal parameter of the LMIs)."""
        return np.asarray(0.5 * (self.points.min(axis=0) + self.points.max(axis=0)))

    @property
    def radius(self) -> Matrix:
        """Half-width of the bounding box of the points (zero for a fixed parameter)."""
        return np.asarray(0.5 * (self.points.max(axis=0) - self.points.min(axis=0)))

    def deviations(self) -> Matrix:
        """The points relative to :attr:`center`, each parameter scaled to ``[-1, 1]``.

        Returns
        -------
        numpy.ndarray, shape (v, p)
            Normalised deviations (zero for a parameter that does not vary).
        """
        radius = self.radius
        scale = np.where(radius > 0.0, radius, 1.0)
        return np.asarray((self.points - self.center) / scale)

    @property
    def scheduled(self) -> tuple[int, ...]:
        """Parameters the storage depends on: finite rate and a range of positive width."""
        assert self.rates is not None
        return tuple(int(k) for k in np.flatnonzero(np.isfinite(self.rates) & (self.radius > 0)))

    def normalised_rates(self) -> Matrix:
        """Rate bounds of the normalised deviations ``delta_k`` of :attr:`scheduled`.

        Returns
        -------
        numpy.ndarray, shape (q,)
            ``rho_k / r_k`` for each scheduled parameter (``r_k`` its radius).
        """
        assert self.rates is not None
        k = list(self.scheduled)
        return np.asarray(self.rates[k] / self.radius[k])

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary.

        Returns
        -------
        dict
            Keys ``directions``, ``points``, ``names`` and ``rates`` (``None`` for ``inf``).
        """
        assert self.rates is not None
        return {"directions": [d.to_dict() for d in self.directions],
                "points": self.points.tolist(), "names": list(self.names),
                "rates": [None if math.isinf(r) else float(r) for r in self.rates]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AffineUncertainty:
        """Rebuild an uncertainty from :meth:`to_dict` output.

        Parameters
        ----------
        data : dict
            Dictionary with keys ``directions``, ``points`` and optionally ``names`` and
            ``rates``.

        Returns
        -------
        AffineUncertainty
            The validated uncertainty.
        """
        rates = data.get("rates")
        return cls(tuple(Direction.from_dict(d) for d in data["directions"]),
                   np.asarray(data["points"]), tuple(data.get("names", ())),
                   None if rates is None else np.array([math.inf if r is None else r
                                                        for r in rates], dtype=np.float64))


def factor(relations: Sequence[Matrix], radius: Matrix) -> tuple[Matrix, Matrix, Matrix]:
    """Rank factorisation of the parameter part of a descriptor relation.

    Parameters
    ----------
    relations : sequence of numpy.ndarray, each shape (n, size)
        ``Gamma_k``, the descriptor relation of each direction over the augmented vector.
    radius : numpy.ndarray, shape (p,)
        Half-width of each parameter's range.

    Returns
    -------
    G : numpy.ndarray, shape (n, r)
        Left factors, scaled by the radii, side by side.
    H : numpy.ndarray, shape (size, r)
        Right factors side by side.
    owner : numpy.ndarray, shape (r,)
        The parameter each column belongs to (``Delta = diag(delta[owner])``).
    """
    lefts, rights, owner = [], [], []
    for k, (gamma, rho) in enumerate(zip(relations, radius, strict=True)):
        if rho == 0.0:  # a fixed parameter: no column
            continue
        u, sing, vt = np.linalg.svd(gamma, full_matrices=False)  # H independent of the radius
        rank = int(np.sum(sing > _RANK_RTOL * max(float(sing[0]) if sing.size else 0.0, 1e-300)))
        lefts.append(rho * u[:, :rank] * sing[:rank])
        rights.append(vt[:rank].T)
        owner += [k] * rank
    n, size = relations[0].shape
    g = np.hstack(lefts) if owner else np.zeros((n, 0))
    h = np.hstack(rights) if owner else np.zeros((size, 0))
    return g, h, np.asarray(owner, dtype=int)


def robust_conditions(label: str, m0: Any, u: Any, v: Matrix, multiplier: Sequence[Any],
                      deltas: Any, outers: Sequence[Any] | None = None
                      ) -> list[MatrixInequality]:
    """The full-block S-procedure conditions for ``M0 + He(U Delta V^T) < 0``.

    Parameters
    ----------
    label : str
        Name of the derivative condition (the multiplier conditions append ``@delta=j``).
    m0 : array or cvxpy expression, shape (s, s)
        Symmetric nominal matrix ``M0``.
    u : array or cvxpy expression, shape (s, r)
        Left factor ``U``.
    v : numpy.ndarray, shape (s, r)
        Right factor ``V``.
    multiplier : sequence
        ``(Q, S, R)``, each ``(r, r)`` (``Q`` and ``R`` symmetric).
    deltas : numpy.ndarray or cvxpy parameter, shape (d, r)
        Diagonals of ``Delta`` at the points of the parameter set.
    outers : sequence, optional
        ``outer(delta_j, delta_j)`` per point (arrays or cvxpy parameters; by default computed
        from ``deltas``, which must then be an array).

    Returns
    -------
    list of MatrixInequality
        The enlarged derivative condition (as ``-[...] >= 0``), then one multiplier condition
        per point.
    """
    q, s, r = multiplier
    if outers is None:
        outers = [np.outer(d, d) for d in deltas]
    size = {"xi": v.shape[0], "w": v.shape[1]}
    full = BlockMatrix(size)
    full.add_quad({"xi": 1.0}, m0)
    full.add_quad({"xi": v.T}, r)
    full.add_he({"xi": 1.0}, u, {"w": 1.0})
    full.add_he({"xi": v.T}, s.T, {"w": 1.0})
    full.add_quad({"w": 1.0}, q)
    out = [MatrixInequality(label, -full.assemble())]
    for j, outer in enumerate(outers):
        point = BlockMatrix({"w": v.shape[1]})
        point.add_quad({"w": 1.0}, r + hadamard(outer, q))  # Delta Q Delta = (d d^T) o Q
        point.add_he({"w": diag(deltas[j])}, s, {"w": 1.0})
        out.append(MatrixInequality(f"{label}@delta={j}", point.assemble()))
    return out
