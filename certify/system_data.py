"""The numbers of a system that its LMIs depend on, as arrays or as cvxpy parameters.

A method's LMIs (:mod:`certify.conditions`) depend on the system only through a few matrices:
per vertex the descriptor relation ``Gamma`` of the vertex at the centre of the uncertainty
(what the Finsler slack multiplies), and for an affine uncertainty the rank factors
``G Delta H^T`` of its part of the relation, with the values of ``Delta`` at the points of
the parameter set. :class:`SystemData` holds them; :meth:`SystemData.parameters` gives cvxpy
parameters of the same shapes, so that one problem built on the parameters serves every system
of the same structure (cvxpy's DPP: built and compiled once, re-solved with new values). The
right factors ``H`` only depend on the parameter directions, not on the parameter ranges, and
stay constants of the problem (they multiply decision matrices from both sides, which DPP does
not allow for parameters).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import cvxpy as cp
import numpy as np
import scipy.sparse

from certify.blocks import Form, form_matrix
from certify.channels import Channels
from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.uncertainty import Direction, factor


class Posed(Protocol):
    """What this module needs of an LMI method (:class:`certify.conditions.LMIMethod`)."""

    def blocks(self, ch: Channels, mu: float | None) -> dict[str, int]:
        """Names and dimensions of the blocks of the augmented vector.

        Parameters
        ----------
        ch : Channels
            The delay channels.
        mu : float or None
            Bound on the delays' derivative (None: unknown).

        Returns
        -------
        dict of str to int
            Block sizes.
        """

    def dynamics(self, vertex: LinearDelaySystem | Direction, ch: Channels) -> Form:
        """Form ``Gamma`` with ``Gamma xi = 0`` along solutions of ``vertex``.

        Parameters
        ----------
        vertex : LinearDelaySystem or Direction
            A vertex system, or a direction of an uncertainty.
        ch : Channels
            The delay channels.

        Returns
        -------
        Form
            The relation's blocks.
        """

__all__ = ["Posed", "SystemData", "dynamics_scale", "eliminable_rows", "relation_kernel",
           "system_data"]


@dataclass(frozen=True, eq=False)
class SystemData:
    """What a method's LMIs take from the system (numpy arrays or cvxpy parameters).

    Parameters
    ----------
    relations : tuple
        Per vertex, the descriptor relation ``Gamma`` (shape ``(n, size)``) of the vertex at
        the centre of the uncertainty, divided by :func:`dynamics_scale`.
    left : Any
        The left rank factors ``G`` of the uncertainty's part of the relation, divided by the
        same scale, shape ``(n, r)`` (``r = 0`` without an uncertainty).
    right : numpy.ndarray
        The right rank factors ``H``, shape ``(size, r)`` (a constant of the problem).
    owner : numpy.ndarray
        The parameter each of the ``r`` columns belongs to.
    deltas : Any
        The diagonal of ``Delta`` at each point of the parameter set, shape ``(d, r)``.
    outers : tuple
        Per point, ``delta delta^T`` (shape ``(r, r)``, separate so that problems stay DPP).
    eliminated : tuple of int
        Rows of the relation eliminated (:func:`eliminable_rows`): the conditions are posed on
        their kernel, ``xi = Z zeta``, and ``relations``, ``left`` and ``right`` hold the other
        rows on ``zeta`` (``Gamma Z``, ``G``, ``Z^T H``).
    kernel : numpy.ndarray or None
        The basis ``Z`` (shape ``(size, size - len(eliminated))``, :func:`relation_kernel`), a
        constant of the problem; ``None`` when no row is eliminated.
    slots : tuple, optional
        For parameters (:meth:`parameters`): the parameter of each relation and of ``left``,
        with the flattened entries it holds; the other entries are structural zeros.
    """

    relations: tuple[Any, ...]
    left: Any
    right: np.ndarray
    owner: np.ndarray
    deltas: Any
    outers: tuple[Any, ...]
    eliminated: tuple[int, ...] = ()
    kernel: np.ndarray | None = None
    slots: tuple[tuple[Any, np.ndarray], ...] = ()

    @property
    def slack_shape(self) -> tuple[int, int]:
        """Shape of the Finsler slack that multiplies these relations: ``(k, rows)``."""
        rows, size = self.relations[0].shape
        return size, rows

    def structure(self) -> tuple[Any, ...]:
        """What two systems must share for one problem to serve both.

        Returns
        -------
        tuple
            The shapes and nonzero patterns of the data and the constant right factors.
        """
        kernel = b"" if self.kernel is None else (self.kernel.shape, self.kernel.tobytes())
        return (tuple((r.shape, np.flatnonzero(r).tobytes()) for r in self._sparse()),
                self.right.tobytes(), self.owner.tobytes(), self.deltas.shape, self.eliminated,
                kernel)

    def _sparse(self) -> tuple[Any, ...]:
        return (*self.relations, self.left)

    def parameters(self) -> SystemData:
        """Parameters (cvxpy) of the same shapes and nonzero patterns, holding these values.

        The relations and ``left`` are parametrised on their nonzero entries only, so the
        problem keeps the sparsity of the system's matrices (a dense parameter would make
        every entry a nonzero of the solver's data, which slows the solve down).

        Returns
        -------
        SystemData
            The parameters (``right`` and ``owner`` are shared constants).
        """
        slots, sparse = [], []
        for k, value in enumerate(self._sparse()):
            support = np.flatnonzero(value)
            param = cp.Parameter(support.size, name=f"data{k}")
            basis = scipy.sparse.csr_array(
                (np.ones(support.size), (support, np.arange(support.size))),
                shape=(value.size, support.size))
            sparse.append(cp.reshape(basis @ param, value.shape, order="C") if support.size
                          else np.zeros(value.shape))
            slots.append((param, support))
        params = SystemData(
            tuple(sparse[:-1]), sparse[-1], self.right, self.owner,
            cp.Parameter(self.deltas.shape, name="delta"),
            tuple(cp.Parameter(o.shape, symmetric=True, name=f"outer{j}")
                  for j, o in enumerate(self.outers)), self.eliminated, self.kernel,
            tuple(slots))
        params.assign(self)
        return params

    def assign(self, values: SystemData) -> None:
        """Set these parameters to the arrays of ``values`` (a system of the same structure).

        Parameters
        ----------
        values : SystemData
            Numeric data with :meth:`structure` equal to the one these parameters were made
            from.
        """
        pairs = [*((param, value.flat[support]) for (param, support), value
                   in zip(self.slots, values._sparse(), strict=True)),
                 (self.deltas, values.deltas), *zip(self.outers, values.outers, strict=True)]
        for param, value in pairs:
            if param.size:
                param.value = value


def dynamics_scale(system: PolytopicDelaySystem) -> float:
    """Largest entry modulus of ``E``, ``A0`` and ``A_i`` over all corners (exact in floats).

    The Finsler slack multiplies the dynamics divided by this scale, which keeps the slack
    of the order of the functional's matrices whatever the units of the system.

    Parameters
    ----------
    system : PolytopicDelaySystem
        The system.

    Returns
    -------
    float
        The scale (at least the smallest normal float).
    """
    mats = [m for v in system.corners() for m in (v.E_matrix, v.A0, *v.A)]
    return max(float(np.finfo(np.float64).tiny), *(float(np.abs(m).max()) for m in mats))


def system_data(method: Posed, system: PolytopicDelaySystem, ch: Channels,
                mu: float | None, eliminated: Sequence[int] | None = None) -> SystemData:
    """The numbers of ``system`` that the LMIs of ``method`` depend on.

    Parameters
    ----------
    method : Posed
        The method (its augmented vector and descriptor relation).
    system : PolytopicDelaySystem
        The system.
    ch : Channels
        Delay channels.
    mu : float or None
        Delay-derivative bound.
    eliminated : sequence of int, optional
        Rows of the relation to eliminate (a certificate's record); by default every row
        :func:`eliminable_rows` finds.

    Returns
    -------
    SystemData
        Numpy arrays.

    Raises
    ------
    ValueError
        If a row of ``eliminated`` cannot be eliminated for this system.
    """
    sizes = method.blocks(ch, mu)
    unit = 1.0 / dynamics_scale(system)
    relations = tuple(unit * form_matrix(method.dynamics(system.nominal(v), ch), sizes, ch.n)
                      for v in system.vertices)
    size = sum(sizes.values())
    factors = parameter_factors(method, system, ch, mu)
    left, right, owner = factors if factors is not None else (
        np.zeros((ch.n, 0)), np.zeros((size, 0)), np.zeros(0, dtype=int))
    unc = system.uncertainty
    deltas = np.zeros((0, 0)) if unc is None else unc.deviations()[:, owner]
    rows = eliminable_rows(relations, left, ch.n) if eliminated is None else tuple(eliminated)
    kernel = relation_kernel(relations, left, ch.n, rows)
    if kernel is not None:
        kept = np.setdiff1d(np.arange(ch.n), rows)
        relations = tuple(r[kept] @ kernel for r in relations)
        left, right = left[kept], kernel.T @ right
    return SystemData(relations, unit * left, right, owner, deltas,
                      tuple(np.outer(d, d) for d in deltas), rows, kernel)


def _pivot(relations: Sequence[np.ndarray], left: np.ndarray, n: int, row: int) -> int | None:
    """The ``dx`` column row ``row`` fixes, if the row can be eliminated (else None).

    It can if it reads ``dx_a = c x_b`` (one entry on ``dx``, one on ``x``, none elsewhere),
    every vertex shares it and no parameter changes it.
    """
    first = relations[0][row]
    on_dx, on_x = np.flatnonzero(first[n:2 * n]), np.flatnonzero(first[:n])
    if (on_dx.size != 1 or on_x.size != 1 or np.count_nonzero(first) != 2
            or np.any(left[row] != 0)
            or not all(np.array_equal(r[row], first) for r in relations)):
        return None
    return n + int(on_dx[0])


def eliminable_rows(relations: Sequence[np.ndarray], left: np.ndarray, n: int
                    ) -> tuple[int, ...]:
    """Kinematic rows of the descriptor relation: ``dx_a = c x_b``, the same at every vertex.

    A row that every vertex shares and no parameter changes, with one entry on the derivative
    block ``dx`` (columns ``n`` to ``2n``) and one on the state ``x``, fixes that derivative:
    a kinematic row ``q' = v`` of a mechanical system. Its kernel is structural (``c`` is 1,
    or a ratio of state scales), so systems of one structure still share one problem; rows
    that mix several states (``x' = A0 x + ...`` of a general system) are left to the slack.
    Posing the conditions on the kernel of such rows
    (:func:`relation_kernel`) is equivalent to multiplying them by the Finsler slack: a
    feasible slack restricts to the kernel, and a kernel solution extends to a slack by adding
    ``-s Gamma_c^T`` on these rows for a large enough ``s``, at every vertex at once. It
    removes one dimension from every derivative condition per row, along which only a large
    slack makes the condition negative and the solver reaches small margins only.

    Parameters
    ----------
    relations : sequence of numpy.ndarray
        Per vertex, the relation ``Gamma`` (shape ``(n, size)``).
    left : numpy.ndarray
        Left rank factors of the uncertainty's part (shape ``(n, r)``).
    n : int
        State dimension.

    Returns
    -------
    tuple of int
        The rows, in order; a row whose derivative an earlier row fixes is left out.
    """
    rows: list[int] = []
    columns: set[int] = set()
    for row in range(n):
        column = _pivot(relations, left, n, row)
        if column is not None and column not in columns:
            rows.append(row)
            columns.add(column)
    return tuple(rows)


def relation_kernel(relations: Sequence[np.ndarray], left: np.ndarray, n: int,
                    rows: Sequence[int]) -> np.ndarray | None:
    """A basis ``Z`` of the vectors ``xi`` that satisfy the relation's ``rows``.

    Each row fixes its derivative entry (:func:`eliminable_rows`): ``Z`` is the identity on the
    other entries, and the row solved for its derivative on that one.

    Parameters
    ----------
    relations : sequence of numpy.ndarray
        Per vertex, the relation ``Gamma`` (shape ``(n, size)``).
    left : numpy.ndarray
        Left rank factors of the uncertainty's part (shape ``(n, r)``).
    n : int
        State dimension.
    rows : sequence of int
        The rows (empty: no kernel).

    Returns
    -------
    numpy.ndarray or None
        ``Z``, shape ``(size, size - len(rows))``; ``None`` for no row.

    Raises
    ------
    ValueError
        If a row cannot be eliminated (out of range, repeated, not shared by every vertex,
        changed by a parameter, not on exactly one derivative, or on one an earlier row fixes).
    """
    if not rows:
        return None
    found = [_pivot(relations, left, n, row) if 0 <= row < n else None for row in rows]
    pivots = [p for p in found if p is not None]
    if len(set(pivots)) != len(rows) or len(set(rows)) != len(rows):
        raise ValueError(f"rows {list(rows)} of the descriptor relation cannot be eliminated "
                         "for this system")
    first = relations[0]
    kept = np.setdiff1d(np.arange(first.shape[1]), pivots)
    kernel = np.zeros((first.shape[1], kept.size))
    kernel[kept, np.arange(kept.size)] = 1.0
    for row, column in zip(rows, pivots, strict=True):
        kernel[column] = -first[row, kept] / first[row, column]
    return kernel


def parameter_factors(method: Posed, system: PolytopicDelaySystem, ch: Channels,
                      mu: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Rank factors ``(G, H, owner)`` of the system's affine uncertainty in a method.

    Parameters
    ----------
    method : Posed
        The method.
    system : PolytopicDelaySystem
        The system.
    ch : Channels
        Delay channels.
    mu : float or None
        Delay-derivative bound.

    Returns
    -------
    tuple or None
        :func:`certify.uncertainty.factor` of the descriptor relation of each direction,
        or ``None`` without an uncertainty (or when no parameter actually varies).
    """
    if system.uncertainty is None:
        return None
    sizes: Mapping[str, int] = method.blocks(ch, mu)
    relations = [form_matrix(method.dynamics(d, ch), sizes, ch.n)
                 for d in system.uncertainty.directions]
    factors = factor(relations, system.uncertainty.radius)
    return factors if factors[0].shape[1] else None
