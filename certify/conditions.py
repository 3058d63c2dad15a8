"""Common frame of the delay-dependent LMI methods.

Every method writes the time derivative of its functional as a quadratic form
``xi^T Phi xi`` in an augmented vector ``xi`` (blocks such as ``x``, ``dx`` and the
delayed states) that satisfies the descriptor relation ``Gamma xi = 0``, i.e.
``-E x' + A0 x + sum_i A_i x(t - tau_i) = 0``. Finsler's lemma with a free slack ``N``
(multiplying the relation divided by :func:`~certify.system_data.dynamics_scale`) turns
"``Phi < 0`` on the kernel of ``Gamma``" into ``Phi + N Gamma + Gamma^T N^T < 0``, which is
affine in ``(E, A0, A_i)``: one common functional and one common slack checked at every vertex
of a polytopic system certify the whole polytope, even for arbitrarily fast variation inside
it. Rows of the relation that every vertex shares and that fix one derivative
(``q' = v``, :func:`~certify.system_data.eliminable_rows`) are not multiplied by the slack:
the conditions are posed on their kernel ``xi = Z zeta``, an equivalent and smaller form.

Where ``Phi`` depends on the current delay value (augmented functionals), it is
convex in the delays and is checked at the vertices of the delay box; the slack may
then differ per delay vertex (multi-affine interpolation keeps the argument exact).
"""

from __future__ import annotations

import copy
import itertools
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from certify.blocks import BlockMatrix, Form, MatrixInequality, bmat
from certify.channels import Channels
from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.system_data import SystemData, parameter_factors, system_data
from certify.uncertainty import Direction, robust_conditions

__all__ = [
    "DelayPoint",
    "LMIMethod",
    "VariableSpec",
    "box_vertices",
    "check_mu",
    "delay_class_text",
    "lower_bounds",
]

DelayPoint = tuple[bool, ...]
"""Which delays sit at their upper bound (``True``) or at their lower bound (``False``)."""


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


def lower_bounds(lower: float | Sequence[float], m: int) -> tuple[float, ...]:
    """Validate lower delay bounds.

    Parameters
    ----------
    lower : float or sequence of float
        One bound per delay, or one for all.
    m : int
        Number of delays.

    Returns
    -------
    tuple of float
        ``m`` bounds.

    Raises
    ------
    ValueError
        On a wrong count, or a bound that is negative or not finite.
    """
    values = np.array(lower, dtype=np.float64).reshape(-1)
    if values.size == 1:
        values = np.full(m, values[0])
    if values.size != m:
        raise ValueError(f"lower needs {m} entries (one per delay), got {values.size}")
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"lower delay bounds must be finite and >= 0, got {values.tolist()}")
    return tuple(float(x) for x in values)


def delay_class_text(mu: float | None, lower: Sequence[float] = ()) -> str:
    """Describe the delay class in words (for certificate assumptions).

    Parameters
    ----------
    mu : float or None
        Delay-derivative bound as in :func:`check_mu`.
    lower : sequence of float, optional
        Lower delay bounds (empty or zero: from 0).

    Returns
    -------
    str
        One-line description.
    """
    low = "l_i" if any(lower) else "0"
    interval = f"[{low}, h_i]"
    if mu is None:
        text = f"delays: each tau_i(t) in {interval}, time-varying with unknown derivative"
    elif mu == 0.0:
        text = (f"delays: each tau_i constant in {interval} (time-invariant, mutually "
                "independent)")
    else:
        text = (f"delays: each tau_i(t) in {interval}, differentiable with tau_i'(t) <= "
                f"mu = {mu:g}")
    if any(lower):
        text += "; l = " + ", ".join(f"{x:g}" for x in lower)
    return text


class LMIMethod(ABC):
    """A delay-dependent stability LMI in the descriptor/Finsler form.

    Subclasses define the augmented vector, the functional's decision matrices, its
    positivity conditions and the quadratic form ``Phi`` of its derivative bound; this
    class adds the Finsler slack and produces the full list of matrix inequalities.
    Delay ``i`` acts through ``y_i = C_i x`` (see :class:`certify.channels.Channels`), so
    its blocks have dimension ``r_i``.
    """

    name: str = ""
    lower: tuple[float, ...] = ()
    """Lower delay bounds ``l_i`` (empty: every delay from 0)."""

    def lower_bound(self, i: int) -> float:
        """Lower bound ``l_i`` of delay ``i`` (0 unless set by :meth:`with_lower`).

        Parameters
        ----------
        i : int
            Delay index.

        Returns
        -------
        float
            The bound.
        """
        return self.lower[i] if self.lower else 0.0

    def with_lower(self, lower: Sequence[float]) -> LMIMethod:
        """The same method for delays ``l_i <= tau_i(t) <= h_i``.

        Parameters
        ----------
        lower : sequence of float
            One lower bound per delay (all zero gives the method itself).

        Returns
        -------
        LMIMethod
            A copy holding the bounds.
        """
        bounds = tuple(float(x) for x in lower)
        if not any(bounds):
            return self
        method = copy.copy(self)
        method.lower = bounds
        return method

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
        self, ch: Channels, mu: float | None, system: PolytopicDelaySystem,
        data: SystemData | None = None,
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
            ``(MQ, MS, MR)`` per derivative condition (named ``"MQ<point>@<vertex>"``), and
            each of its rate-bounded parameters a storage direction ``dP<k>`` per copy (with a
            rate bound ``Z<k>`` for a positive rate).
        data : SystemData, optional
            The system's numbers (:func:`certify.system_data.system_data` by default), which
            fix the shape of the slacks: one row per component of the reduced vector
            ``zeta``, one column per relation row kept.

        Returns
        -------
        list of VariableSpec
            Variable shapes.
        """
        data = system_data(self, system, ch, mu) if data is None else data
        points = range(len(self.delay_points(ch.m, mu)))
        slacks = [VariableSpec(f"N{j}", data.slack_shape, symmetric=False) for j in points
                  if data.slack_shape[1]]  # none when every row of the relation is eliminated
        copies = _copies(system)
        own = self.functional_variables(ch, mu) + [
            VariableSpec(name, (ch.n, ch.n), True) for name in _storage_names(system)]
        if copies > 1:
            own = [
                VariableSpec(f"{s.name}@{k}", s.shape, s.symmetric)
                for k in range(copies)
                for s in own
            ]
        width = self._uncertainty_width(system, ch, mu)
        if width == 0:
            return own + slacks
        multipliers = [
            VariableSpec(f"{name}{j}@{k}", (width, width), name != "MS")
            for j in points
            for k in range(len(system.vertices))
            for name in ("MQ", "MS", "MR")
        ]
        return own + slacks + multipliers

    def _uncertainty_width(self, system: PolytopicDelaySystem, ch: Channels,
                           mu: float | None) -> int:
        """Size of ``Delta``: the rank of the parameter part plus ``n`` per storage direction."""
        factors = parameter_factors(self, system, ch, mu)
        rank = 0 if factors is None else factors[0].shape[1]
        scheduled = () if system.uncertainty is None else system.uncertainty.scheduled
        return rank + ch.n * len(scheduled)

    def conditions(
        self,
        system: PolytopicDelaySystem,
        ch: Channels,
        var: Mapping[str, Any],
        h: Sequence[Any],
        h2: Sequence[Any],
        mu: float | None,
        data: SystemData | None = None,
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
        data : SystemData, optional
            What the conditions take from the system (:func:`certify.system_data.system_data`
            by default); cvxpy parameters of the same shapes give a problem that serves every
            system of the same structure.

        Returns
        -------
        list of MatrixInequality
            Positivity conditions, then the derivative conditions per (delay point, vertex),
            each followed by its multiplier conditions if there is an uncertainty.
        """
        data = system_data(self, system, ch, mu) if data is None else data
        copies = _copies(system)
        names = [s.name for s in self.functional_variables(ch, mu)] + _storage_names(system)
        own = [{x: var[f"{x}@{k}" if copies > 1 else x] for x in names} for k in range(copies)]
        storage = _Storage(system, ch, self.blocks(ch, mu))
        out = []
        for k, matrices in enumerate(own):
            for cond in storage.positivity(self, matrices, ch, mu):
                label = f"{cond.name}@{k}" if copies > 1 else cond.name
                out.append(MatrixInequality(label, cond.matrix, cond.normalise))
        for j, point in enumerate(self.delay_points(ch.m, mu)):
            phis = []
            for mats in own:
                phi = self.derivative(mats, ch, h, h2, point, mu)
                storage.add_rate_term(phi, mats)
                phis.append(_on_kernel(phi.assemble(), data.kernel))
            slack = var.get(f"N{j}")
            tag = "".join("h" if p else "0" for p in point)
            for k, relation in enumerate(data.relations):
                mats = own[k if copies > 1 else 0]
                m0 = phis[k if copies > 1 else 0]
                if slack is not None:
                    finsler = slack @ relation
                    m0 = m0 + finsler + finsler.T
                label = f"derivative[vertex={k},tau={tag}]"
                if data.right.shape[1] + storage.width == 0:
                    out.append(MatrixInequality(label, -m0))
                    continue
                multiplier = [var[f"{name}{j}@{k}"] for name in ("MQ", "MS", "MR")]
                u = slack @ data.left if data.right.shape[1] else None
                u, right, deltas = storage.extend(u, data.right, data.deltas, mats,
                                                  data.kernel)
                outers = None if storage.scheduled else data.outers  # else computed from deltas
                out += robust_conditions(label, m0, u, right, multiplier, deltas, outers)
        return out


def _storage_names(system: PolytopicDelaySystem) -> list[str]:
    """Names of the storage directions ``dP<k>`` and rate bounds ``Z<k>`` of a system."""
    unc = system.uncertainty
    if unc is None:
        return []
    rates = unc.normalised_rates()
    return ([f"dP{k}" for k in unc.scheduled]
            + [f"Z{k}" for k, rate in zip(unc.scheduled, rates, strict=True) if rate > 0])


class _Storage:
    """The storage's dependence on rate-bounded parameters (see :mod:`certify.uncertainty`)."""

    def __init__(self, system: PolytopicDelaySystem, ch: Channels,
                 sizes: dict[str, int]) -> None:
        unc = system.uncertainty
        self.scheduled = () if unc is None else unc.scheduled
        self.rates = np.zeros(0) if unc is None else unc.normalised_rates()
        self.deviations = (np.zeros((0, 0)) if unc is None
                           else unc.deviations()[:, list(self.scheduled)])
        self.n = ch.n
        self.size = sum(sizes.values())
        self.width = ch.n * len(self.scheduled)

    def _directions(self, mats: Mapping[str, Any]) -> list[Any]:
        return [mats[f"dP{k}"] for k in self.scheduled]

    def positivity(self, method: LMIMethod, mats: Mapping[str, Any], ch: Channels,
                   mu: float | None) -> list[MatrixInequality]:
        """The method's positivity with its storage at every parameter point; ``Z_k >= +-dP_k``."""
        conditions = method.positivity(mats, ch, mu)
        if not self.scheduled:
            return conditions
        out = [c for c in conditions if c.name != "P"]
        for j, delta in enumerate(self.deviations):
            change = sum(d * dp for d, dp in zip(delta, self._directions(mats), strict=True))
            p = mats["P"]
            pad = p.shape[0] - self.n
            if pad:
                change = bmat([[change, np.zeros((self.n, pad))],
                               [np.zeros((pad, self.n)), np.zeros((pad, pad))]])
            moved = {**mats, "P": p + change}
            storage = [c for c in method.positivity(moved, ch, mu) if c.name == "P"]
            out += [MatrixInequality(f"P@delta={j}", c.matrix, c.normalise) for c in storage]
        for k, dp, rate in zip(self.scheduled, self._directions(mats), self.rates, strict=True):
            if rate > 0:
                z = mats[f"Z{k}"]
                out += [MatrixInequality(f"Z{k}-dP{k}", z - dp),
                        MatrixInequality(f"Z{k}+dP{k}", z + dp)]
        return out

    def add_rate_term(self, phi: BlockMatrix, mats: Mapping[str, Any]) -> None:
        """Add the bound ``x^T (sum_k rho_k Z_k) x`` of ``x^T P'(t) x`` to ``phi``."""
        for k, rate in zip(self.scheduled, self.rates, strict=True):
            if rate > 0:
                phi.add_quad({"x": 1.0}, rate * mats[f"Z{k}"])

    def extend(self, u: Any, v: np.ndarray, deltas: np.ndarray, mats: Mapping[str, Any],
               kernel: np.ndarray | None) -> tuple[Any, np.ndarray, np.ndarray]:
        """Append the storage term ``He(U_P Delta_P V_P^T)`` to the factors of ``Delta``.

        ``u`` is ``None`` when no parameter changes the dynamics (``v`` has no column); ``u``
        and ``v`` are on the kernel of the eliminated relation rows (``kernel``), and so are
        the storage's factors once appended.
        """
        if not self.scheduled:
            return u, v, deltas
        rest = self.size - self.n
        q = len(self.scheduled)
        u_p = bmat([self._directions(mats), [np.zeros((rest, self.n))] * q])
        v_p = np.zeros((self.size, self.width))
        for k in range(q):
            v_p[self.n:2 * self.n, k * self.n:(k + 1) * self.n] = np.eye(self.n)
        if kernel is not None:
            u_p, v_p = kernel.T @ u_p, kernel.T @ v_p
        columns = np.repeat(self.deviations, self.n, axis=1)
        return (u_p if u is None else bmat([[u, u_p]]), np.hstack([v, v_p]),
                np.hstack([deltas, columns]))


def _on_kernel(phi: Any, kernel: np.ndarray | None) -> Any:
    """``Z^T Phi Z``: the quadratic form on ``xi = Z zeta`` (``Phi`` itself without a kernel)."""
    return phi if kernel is None else kernel.T @ phi @ kernel


def _copies(system: PolytopicDelaySystem) -> int:
    """Copies of the functional's matrices: one per vertex for a frozen parameter, else 1."""
    return len(system.vertices) if system.frozen and len(system.vertices) > 1 else 1


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
