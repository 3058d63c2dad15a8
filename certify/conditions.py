"""Common frame of the delay-dependent LMI methods.

Every method writes the time derivative of its functional as a quadratic form
``xi^T Phi xi`` in an augmented vector ``xi`` (blocks such as ``x``, ``dx`` and the
delayed states) that satisfies the descriptor relation ``Gamma xi = 0``, i.e.
``-E x' + A0 x + sum_i A_i x(t - tau_i) = 0``. Finsler's lemma with a free slack ``N``
(multiplying the relation divided by :func:`dynamics_scale`) turns "``Phi < 0`` on the
kernel of ``Gamma``" into ``Phi + N Gamma + Gamma^T N^T < 0``, which is affine in
``(E, A0, A_i)``: one common functional and one common slack checked at every vertex of a
polytopic system certify the whole polytope, even for arbitrarily fast variation inside it.

Where ``Phi`` depends on the current delay value (augmented functionals), it is
convex in the delays and is checked at the vertices of the delay box; the slack may
then differ per delay vertex (multi-affine interpolation keeps the argument exact).
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from certify.blocks import BlockMatrix, Form, MatrixInequality, form_matrix
from certify.channels import Channels
from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.uncertainty import Direction, factor, robust_conditions

__all__ = [
    "DelayPoint",
    "LMIMethod",
    "VariableSpec",
    "box_vertices",
    "check_mu",
    "delay_class_text",
    "dynamics_scale",
]

DelayPoint = tuple[bool, ...]
"""Which delays sit at their upper bound (``True``) or at zero (``False``)."""


@dataclass(frozen=True)
class VariableSpec:
    """Shape of one decision matrix.

    Parameters
    ----------
    name : str
        Variable name (key in a certificate's ``matrices``).
    shape : tuple of int
        Matrix shape.
    symmetric : bool
        Whether the matrix is symmetric.
    """

    name: str
    shape: tuple[int, int]
    symmetric: bool


def check_mu(mu: float | None) -> float | None:
    """Validate a delay-derivative bound.

    Parameters
    ----------
    mu : float or None
        ``None`` (fast-varying delays), ``0.0`` (constant delays) or a bound in ``(0, 1)``
        on ``tau_i'(t)``.

    Returns
    -------
    float or None
        ``mu`` as a float (or ``None``).

    Raises
    ------
    ValueError
        If ``mu`` is not ``None`` and not in ``[0, 1)``.
    """
    if mu is None:
        return None
    value = float(mu)
    if not 0.0 <= value < 1.0:
        raise ValueError(f"mu must be None or in [0, 1), got {mu!r}")
    return value


def delay_class_text(mu: float | None) -> str:
    """Describe the delay class in words (for certificate assumptions).

    Parameters
    ----------
    mu : float or None
        Delay-derivative bound as in :func:`check_mu`.

    Returns
    -------
    str
        One-line description.
    """
    if mu is None:
        return "delays: each tau_i(t) in [0, h_i], time-varying with unknown derivative"
    if mu == 0.0:
        return "delays: each tau_i constant in [0, h_i] (time-invariant, mutually independent)"
    return f"delays: each tau_i(t) in [0, h_i], differentiable with tau_i'(t) <= mu = {mu:g}"


class LMIMethod(ABC):
    """A delay-dependent stability LMI in the descriptor/Finsler form.

    Subclasses define the augmented vector, the functional's decision matrices, its
    positivity conditions and the quadratic form ``Phi`` of its derivative bound; this
    class adds the Finsler slack and produces the full list of matrix inequalities.
    Delay ``i`` acts through ``y_i = C_i x`` (see :class:`certify.channels.Channels`), so
    its blocks have dimension ``r_i``.
    """

    name: str = ""

    @abstractmethod
    def blocks(self, ch: Channels, mu: float | None) -> dict[str, int]:
        """Names and dimensions of the blocks of the augmented vector ``xi``.

        Parameters
        ----------
        ch : Channels
            Delay channels.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        dict
            Ordered block name -> dimension, ``"x"`` and ``"dx"`` first.
        """

    @abstractmethod
    def functional_variables(self, ch: Channels, mu: float | None) -> list[VariableSpec]:
        """Decision matrices of the functional (or multiplier), slack excluded.

        Parameters
        ----------
        ch : Channels
            Delay channels.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        list of VariableSpec
            Variable shapes.
        """

    @abstractmethod
    def delay_points(self, m: int, mu: float | None) -> list[DelayPoint]:
        """Delay values at which ``Phi`` must be checked.

        Parameters
        ----------
        m : int
            Number of delays.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        list of DelayPoint
            Vertices of the delay box (a single point when ``Phi`` does not depend on it).
        """

    @abstractmethod
    def positivity(
        self, var: Mapping[str, Any], ch: Channels, mu: float | None
    ) -> list[MatrixInequality]:
        """Conditions making the functional positive (or the multipliers valid).

        Parameters
        ----------
        var : Mapping[str, Any]
            Decision matrices (numpy arrays or cvxpy variables).
        ch : Channels
            Delay channels.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        list of MatrixInequality
            Conditions ``matrix >= 0``; their traces normalise the problem's scale.
        """

    @abstractmethod
    def derivative(
        self,
        var: Mapping[str, Any],
        ch: Channels,
        h: Sequence[Any],
        h2: Sequence[Any],
        point: DelayPoint,
        mu: float | None,
    ) -> BlockMatrix:
        """Quadratic form ``Phi`` bounding the derivative (without the Finsler slack).

        Parameters
        ----------
        var : Mapping[str, Any]
            Decision matrices.
        ch : Channels
            Delay channels.
        h : sequence
            Delay upper bounds ``h_i`` (floats or cvxpy parameters).
        h2 : sequence
            Their squares (separate so that cvxpy problems stay DPP).
        point : DelayPoint
            Delay vertex at which ``Phi`` is evaluated.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        BlockMatrix
            ``Phi`` over :meth:`blocks`.
        """

    @abstractmethod
    def dynamics(self, vertex: LinearDelaySystem | Direction, ch: Channels) -> Form:
        """Form ``Gamma`` with ``Gamma xi = 0`` along solutions of the vertex system.

        Parameters
        ----------
        vertex : LinearDelaySystem or Direction
            One vertex of the system (or a parameter direction, for the part of the
            relation that changes with the parameter).
        ch : Channels
            Delay channels.

        Returns
        -------
        Form
            The descriptor relation in terms of the blocks of ``xi``.
        """

    @abstractmethod
    def assumptions(self, mu: float | None) -> list[str]:
        """Method-specific assumptions stated by a certificate.

        Parameters
        ----------
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        list of str
            Human-readable assumptions.
        """

    def variables(
        self, ch: Channels, mu: float | None, system: PolytopicDelaySystem
    ) -> list[VariableSpec]:
        """All decision matrices: the functional's, the Finsler slacks and the multipliers.

        Parameters
        ----------
        ch : Channels
            Delay channels.
        mu : float or None
            Delay-derivative bound.
        system : PolytopicDelaySystem
            The system: a frozen parameter gets one copy of the functional's matrices per
            vertex (named ``"<name>@<vertex>"``), an affine uncertainty one multiplier
            ``(MQ, MS, MR)`` per derivative condition (named ``"MQ<point>@<vertex>"``).

        Returns
        -------
        list of VariableSpec
            Variable shapes.
        """
        size = sum(self.blocks(ch, mu).values())
        points = range(len(self.delay_points(ch.m, mu)))
        slacks = [VariableSpec(f"N{j}", (size, ch.n), symmetric=False) for j in points]
        own = self.functional_variables(ch, mu)
        copies = _copies(system)
        if copies > 1:
            own = [
                VariableSpec(f"{s.name}@{k}", s.shape, s.symmetric)
                for k in range(copies)
                for s in own
            ]
        factors = self.parameter_factors(system, ch, mu)
        if factors is None:
            return own + slacks
        r = factors[0].shape[1]
        multipliers = [
            VariableSpec(f"{name}{j}@{k}", (r, r), name != "MS")
            for j in points
            for k in range(len(system.vertices))
            for name in ("MQ", "MS", "MR")
        ]
        return own + slacks + multipliers

    def parameter_factors(
        self, system: PolytopicDelaySystem, ch: Channels, mu: float | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Rank factors ``(G, H, owner)`` of the system's affine uncertainty in this method.

        Parameters
        ----------
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
        sizes = self.blocks(ch, mu)
        relations = [form_matrix(self.dynamics(d, ch), sizes, ch.n)
                     for d in system.uncertainty.directions]
        factors = factor(relations, system.uncertainty.radius)
        return factors if factors[0].shape[1] else None

    def conditions(
        self,
        system: PolytopicDelaySystem,
        ch: Channels,
        var: Mapping[str, Any],
        h: Sequence[Any],
        h2: Sequence[Any],
        mu: float | None,
    ) -> list[MatrixInequality]:
        """All matrix inequalities of the method for a polytopic system.

        The slack is common to all vertices. The functional's matrices are common too for
        a switching parameter, and vertex-wise (the functional is then affine in the
        parameter) for a frozen one; both make every condition affine in the parameter.
        With an affine uncertainty, each derivative condition is centred on it and
        enlarged by its multiplier (:func:`certify.uncertainty.robust_conditions`).

        Parameters
        ----------
        system : PolytopicDelaySystem
            The system (one or several vertices).
        ch : Channels
            Delay channels of the system.
        var : Mapping[str, Any]
            Decision matrices (numpy arrays for a re-check, cvxpy variables to solve).
        h : sequence
            Delay upper bounds, one per delay.
        h2 : sequence
            Their squares.
        mu : float or None
            Delay-derivative bound.

        Returns
        -------
        list of MatrixInequality
            Positivity conditions, then the derivative conditions per (delay point, vertex),
            each followed by its multiplier conditions if there is an uncertainty.
        """
        sizes = self.blocks(ch, mu)
        offsets = np.cumsum([0, *sizes.values()])
        unit = 1.0 / dynamics_scale(system)
        copies = _copies(system)
        names = [s.name for s in self.functional_variables(ch, mu)]
        own = [{x: var[f"{x}@{k}" if copies > 1 else x] for x in names} for k in range(copies)]
        factors = self.parameter_factors(system, ch, mu)
        out = []
        for k, matrices in enumerate(own):
            for cond in self.positivity(matrices, ch, mu):
                label = f"{cond.name}@{k}" if copies > 1 else cond.name
                out.append(MatrixInequality(label, cond.matrix, cond.normalise))
        for j, point in enumerate(self.delay_points(ch.m, mu)):
            phis = [self.derivative(mats, ch, h, h2, point, mu).assemble() for mats in own]
            slack = var[f"N{j}"]
            tag = "".join("h" if p else "0" for p in point)
            for k, vertex in enumerate(system.vertices):
                finsler = BlockMatrix(sizes)
                gamma = self.dynamics(system.nominal(vertex), ch)
                for b, block in enumerate(sizes):
                    rows = slack[offsets[b] : offsets[b + 1], :]
                    finsler.add_he({block: unit}, rows, gamma)
                m0 = phis[k if copies > 1 else 0] + finsler.assemble()
                label = f"derivative[vertex={k},tau={tag}]"
                if factors is None:
                    out.append(MatrixInequality(label, -m0))
                    continue
                assert system.uncertainty is not None
                g, v, owner = factors
                multiplier = [var[f"{name}{j}@{k}"] for name in ("MQ", "MS", "MR")]
                deltas = system.uncertainty.deviations()[:, owner]
                out += robust_conditions(label, m0, unit * (slack @ g), v, multiplier, deltas)
        return out


def _copies(system: PolytopicDelaySystem) -> int:
    """Copies of the functional's matrices: one per vertex for a frozen parameter, else 1."""
    return len(system.vertices) if system.frozen and len(system.vertices) > 1 else 1


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


def box_vertices(m: int) -> list[DelayPoint]:
    """All ``2**m`` vertices of the delay box, each delay at zero or at its bound.

    Parameters
    ----------
    m : int
        Number of delays.

    Returns
    -------
    list of DelayPoint
        The vertices.
    """
    return [tuple(p) for p in itertools.product((False, True), repeat=m)]
