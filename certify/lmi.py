"""Lyapunov–Krasovskii LMIs: Jensen, reciprocally convex and Wirtinger bounds.

One parametrised family covers the three methods. For each delay ``i`` the functional is

``V = z^T P z + int_{t-h_i}^t y_i^T Q_i y_i + [mu] int_{t-tau_i}^t y_i^T U_i y_i
+ h_i int_{-h_i}^0 int_{t+s}^t y_i'^T R_i y_i'``

(with ``h_i`` replaced by ``tau_i`` for constant delays), where ``z = x`` for first-order
methods and ``z = [x; int y_i]`` (one integral per delay) for the Wirtinger method.
The integral ``h int x'^T R x'`` is bounded below by the Jensen (order 1) or the
Wirtinger (order 2, Seuret & Gouaisbaut 2013) inequality, on ``[t - tau, t]`` for
constant delays and on the two sub-intervals ``[t - tau, t]`` and ``[t - h, t - tau]`` for
time-varying ones, combined either with the bound ``1/alpha >= 1`` (plain Jensen) or by
the reciprocally convex combination (Park, Ko & Jeong 2011).

The integral terms act on the delayed signal ``y_i = C_i x`` of each channel (see
:mod:`certify.channels`; ``C_i = I`` for full-rank ``A_i``). Blocks of the augmented
vector: ``x``, ``dx = x'``, ``d_i = y_i(t - tau_i)``, for time-varying delays
``b_i = y_i(t - h_i)``, and for order 2 the averages ``v_i`` of ``y_i`` over
``[t - tau_i, t]`` and ``w_i`` over ``[t - h_i, t - tau_i]``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from certify.blocks import BlockMatrix, Form, MatrixInequality
from certify.channels import Channels
from certify.conditions import DelayPoint, LMIMethod, VariableSpec, box_vertices
from certify.system import LinearDelaySystem
from certify.uncertainty import Direction

__all__ = ["JENSEN", "RECIPROCAL", "WIRTINGER", "LyapunovKrasovskii"]

_LEGENDRE_WEIGHTS = (1.0, 3.0)


class LyapunovKrasovskii(LMIMethod):
    """Delay-dependent LK functional with Jensen- or Wirtinger-type integral bounds.

    Parameters
    ----------
    name : str
        Method name used in certificates.
    order : int
        1 for the Jensen inequality, 2 for the Wirtinger inequality (which also augments
        the quadratic term with the integrals of the delayed signals).
    reciprocal : bool
        Combine the two sub-interval bounds of a time-varying delay by the reciprocally
        convex lemma (otherwise by ``1/alpha >= 1``). Irrelevant for constant delays.
    """

    def __init__(self, name: str, order: int, reciprocal: bool) -> None:
        if order not in (1, 2):
            raise ValueError(f"order must be 1 or 2, got {order}")
        self.name = name
        self.order = order
        self.reciprocal = reciprocal

    def _rcc(self, mu: float | None) -> bool:
        return self.reciprocal and mu != 0.0

    @staticmethod
    def _slow(mu: float | None) -> bool:
        """Whether the functional has the ``U_i`` term of slowly varying delays."""
        return mu is not None and mu != 0.0

    def blocks(self, ch: Channels, mu: float | None) -> dict[str, int]:  # noqa: D102
        names = {"x": ch.n, "dx": ch.n}
        for i, r in enumerate(ch.r):
            keys = ["d"] if mu == 0.0 else ["d", "b"]
            if self.order == 2:
                keys += ["v"] if mu == 0.0 else ["v", "w"]
            names.update({f"{k}{i}": r for k in keys})
        return names

    def functional_variables(  # noqa: D102
        self, ch: Channels, mu: float | None
    ) -> list[VariableSpec]:
        p_size = ch.n + sum(ch.r) if self.order == 2 else ch.n
        out = [VariableSpec("P", (p_size, p_size), symmetric=True)]
        for i, r in enumerate(ch.r):
            out += [VariableSpec(f"Q{i}", (r, r), True), VariableSpec(f"R{i}", (r, r), True)]
            if self._slow(mu):
                out.append(VariableSpec(f"U{i}", (r, r), True))
            if self._rcc(mu):
                out.append(VariableSpec(f"X{i}", (self.order * r, self.order * r), False))
        return out

    def delay_points(self, m: int, mu: float | None) -> list[DelayPoint]:  # noqa: D102
        return box_vertices(m) if self.order == 2 else [(True,) * m]

    def positivity(  # noqa: D102
        self, var: Mapping[str, Any], ch: Channels, mu: float | None
    ) -> list[MatrixInequality]:
        out = [MatrixInequality("P", var["P"], normalise=True)]
        for i, r in enumerate(ch.r):
            out.append(MatrixInequality(f"Q{i}", var[f"Q{i}"], normalise=True))
            if self._slow(mu):
                out.append(MatrixInequality(f"U{i}", var[f"U{i}"], normalise=True))
            if self._rcc(mu):
                out.append(MatrixInequality(f"RCC{i}", self._rcc_matrix(var, i, r), True))
            else:
                out.append(MatrixInequality(f"R{i}", var[f"R{i}"], normalise=True))
        return out

    def derivative(  # noqa: D102
        self,
        var: Mapping[str, Any],
        ch: Channels,
        h: Sequence[Any],
        h2: Sequence[Any],
        point: DelayPoint,
        mu: float | None,
    ) -> BlockMatrix:
        phi = BlockMatrix(self.blocks(ch, mu))
        self._add_quadratic_term(phi, var, ch, h, point, mu)
        for i in range(ch.m):
            c = ch.coef(i)
            end = f"d{i}" if mu == 0.0 else f"b{i}"
            phi.add_quad({"x": c}, var[f"Q{i}"])
            phi.add_quad({end: 1.0}, -var[f"Q{i}"])
            if self._slow(mu):
                phi.add_quad({"x": c}, var[f"U{i}"])
                phi.add_quad({f"d{i}": 1.0}, -(1.0 - float(mu or 0.0)) * var[f"U{i}"])
            if point[i] or mu != 0.0:
                phi.add_quad({"dx": c}, h2[i] * var[f"R{i}"])
            self._add_integral_bound(phi, var, ch, i, mu)
        return phi

    def dynamics(self, vertex: LinearDelaySystem | Direction, ch: Channels) -> Form:  # noqa: D102
        form: dict[str, Any] = {"x": vertex.A0, "dx": -vertex.E_matrix}
        form.update({f"d{i}": ch.input_matrix(vertex, i) for i in range(ch.m)})
        return form

    def assumptions(self, mu: float | None) -> list[str]:  # noqa: D102
        bound = "Jensen" if self.order == 1 else "Wirtinger (Seuret & Gouaisbaut 2013)"
        if mu == 0.0:
            how = "on [t - tau_i, t]"
        elif self._rcc(mu):
            how = "on both sub-intervals, reciprocally convex combination (Park et al. 2011)"
        else:
            how = "on both sub-intervals, combined by 1/alpha >= 1"
        return [f"Lyapunov-Krasovskii functional; {bound} inequality {how}"]

    def _segments(self, ch: Channels, i: int, mu: float | None) -> list[list[Form]]:
        """Forms entering the integral bound, per sub-interval (one or two)."""
        first = self._legendre(("x", ch.coef(i)), f"d{i}", f"v{i}")
        if mu == 0.0:
            return [first]
        return [first, self._legendre((f"d{i}", 1.0), f"b{i}", f"w{i}")]

    def _legendre(self, top: tuple[str, Any], bottom: str, average: str) -> list[Form]:
        """Legendre-type forms of one interval: difference, then (order 2) the mean term."""
        forms: list[Form] = [{top[0]: top[1], bottom: -1.0}]
        if self.order == 2:
            forms.append({top[0]: top[1], bottom: 1.0, average: -2.0})
        return forms

    def _add_quadratic_term(
        self,
        phi: BlockMatrix,
        var: Mapping[str, Any],
        ch: Channels,
        h: Sequence[Any],
        point: DelayPoint,
        mu: float | None,
    ) -> None:
        """Add the derivative of ``z^T P z`` (``z`` augmented by signal integrals if order 2)."""
        if self.order == 1:
            phi.add_he({"x": 1.0}, var["P"], {"dx": 1.0})
            return
        z: list[Form] = [{"x": 1.0}]
        dz: list[Form] = [{"dx": 1.0}]
        for i, hi in enumerate(h):
            if mu == 0.0:
                z.append({f"v{i}": hi} if point[i] else {})
                dz.append({"x": ch.coef(i), f"d{i}": -1.0})
            else:
                z.append({f"v{i}": hi} if point[i] else {f"w{i}": hi})
                dz.append({"x": ch.coef(i), f"b{i}": -1.0})
        p = var["P"]
        cuts = np.cumsum([0, ch.n, *ch.r])
        for a, za in enumerate(z):
            for b, zb in enumerate(dz):
                phi.add_he(za, p[cuts[a] : cuts[a + 1], cuts[b] : cuts[b + 1]], zb)

    def _add_integral_bound(
        self, phi: BlockMatrix, var: Mapping[str, Any], ch: Channels, i: int, mu: float | None
    ) -> None:
        """Subtract the lower bound of ``h_i int y_i'^T R_i y_i'`` over the delay interval."""
        segments = self._segments(ch, i, mu)
        r = var[f"R{i}"]
        for seg in segments:
            for weight, form in zip(_LEGENDRE_WEIGHTS, seg, strict=False):
                phi.add_quad(form, -weight * r)
        if self._rcc(mu):
            x, k = var[f"X{i}"], ch.r[i]
            for a, fa in enumerate(segments[0]):
                for b, fb in enumerate(segments[1]):
                    phi.add_he(fa, -x[a * k : (a + 1) * k, b * k : (b + 1) * k], fb)

    def _rcc_matrix(self, var: Mapping[str, Any], i: int, k: int) -> Any:
        """``[[R~, X], [X^T, R~]]`` with ``R~ = diag(R, 3R)`` (first ``order`` blocks)."""
        keys = [f"s{s}_{j}" for s in range(2) for j in range(self.order)]
        mat = BlockMatrix(dict.fromkeys(keys, k))
        r, x = var[f"R{i}"], var[f"X{i}"]
        for j in range(self.order):
            for s in range(2):
                mat.add_quad({f"s{s}_{j}": 1.0}, _LEGENDRE_WEIGHTS[j] * r)
            for j2 in range(self.order):
                block = x[j * k : (j + 1) * k, j2 * k : (j2 + 1) * k]
                mat.add_he({f"s0_{j}": 1.0}, block, {f"s1_{j2}": 1.0})
        return mat.assemble()


JENSEN = LyapunovKrasovskii("jensen", order=1, reciprocal=False)
RECIPROCAL = LyapunovKrasovskii("rcc", order=1, reciprocal=True)
WIRTINGER = LyapunovKrasovskii("wirtinger", order=2, reciprocal=True)
