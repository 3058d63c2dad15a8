"""Lyapunov–Krasovskii LMIs: Jensen, reciprocally convex and Wirtinger bounds.

One parametrised family covers the three methods, for delays in an interval
``l_i <= tau_i(t) <= h_i`` (``l_i = 0`` by default). For each delay ``i`` the functional is

``V = z^T P z + int_{t-l_i}^t y_i^T Qa_i y_i + int_{t-h_i}^{t-l_i} y_i^T Q_i y_i
+ [mu] int_{t-tau_i}^t y_i^T U_i y_i + l_i int_{-l_i}^0 int_{t+s}^t y_i'^T Ra_i y_i'
+ (h_i - l_i) int_{-h_i}^{-l_i} int_{t+s}^t y_i'^T R_i y_i'``

(the ``Qa_i``, ``Ra_i`` terms only for ``l_i > 0``; for constant delays the single interval
``[t - tau_i, t]`` with ``tau_i`` in place of ``h_i``), where ``z = x`` for first-order methods
and ``z`` is ``x`` augmented with the integrals of the delayed signals over each interval for
the Wirtinger method (He et al. 2007; Park, Ko & Jeong 2011; Seuret & Gouaisbaut 2013).
The integral ``(h - l) int y'^T R y'`` is bounded below by the Jensen (order 1) or the
Wirtinger (order 2) inequality, on ``[t - tau, t]`` for constant delays and on the two
sub-intervals ``[t - tau, t - l]`` and ``[t - h, t - tau]`` for time-varying ones, combined
either with the bound ``1/alpha >= 1`` (plain Jensen) or by the reciprocally convex combination
(Park, Ko & Jeong 2011).

The integral terms act on the delayed signal ``y_i = C_i x`` of each channel (see
:mod:`certify.channels`). Blocks of the augmented vector: ``x``, ``dx = x'``,
``d_i = y_i(t - tau_i)``, for time-varying delays ``b_i = y_i(t - h_i)`` (and ``a_i =
y_i(t - l_i)`` for ``l_i > 0``), and for order 2 the averages ``v_i`` of ``y_i`` over the
interval ending at ``t - tau_i`` from above, ``w_i`` over ``[t - h_i, t - tau_i]`` and
``u_i`` over ``[t - l_i, t]``.

Where the derivative bound depends on the current delay (order 2, or an interval of constant
delays), it is convex in it and is checked at both ends of each delay interval.
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

    def _interval(self, i: int, mu: float | None) -> bool:
        """Whether time-varying delay ``i`` has a positive lower bound (the ``a_i`` blocks)."""
        return mu != 0.0 and self.lower_bound(i) > 0.0

    def blocks(self, ch: Channels, mu: float | None) -> dict[str, int]:  # noqa: D102
        names = {"x": ch.n, "dx": ch.n}
        for i, r in enumerate(ch.r):
            keys = ["d"] if mu == 0.0 else ["d", "b"]
            if self.order == 2:
                keys += ["v"] if mu == 0.0 else ["v", "w"]
            if self._interval(i, mu):
                keys += ["a", "u"] if self.order == 2 else ["a"]
            names.update({f"{k}{i}": r for k in keys})
        return names

    def _integrals(self, ch: Channels, mu: float | None) -> int:
        """Size of the signal integrals augmenting ``z`` (order 2)."""
        return sum(r * (2 if self._interval(i, mu) else 1) for i, r in enumerate(ch.r))

    def functional_variables(  # noqa: D102
        self, ch: Channels, mu: float | None
    ) -> list[VariableSpec]:
        p_size = ch.n + (self._integrals(ch, mu) if self.order == 2 else 0)
        out = [VariableSpec("P", (p_size, p_size), symmetric=True)]
        for i, r in enumerate(ch.r):
            out += [VariableSpec(f"Q{i}", (r, r), True), VariableSpec(f"R{i}", (r, r), True)]
            if self._interval(i, mu):
                out += [VariableSpec(f"Qa{i}", (r, r), True), VariableSpec(f"Ra{i}", (r, r), True)]
            if self._slow(mu):
                out.append(VariableSpec(f"U{i}", (r, r), True))
            if self._rcc(mu):
                out.append(VariableSpec(f"X{i}", (self.order * r, self.order * r), False))
        return out

    def delay_points(self, m: int, mu: float | None) -> list[DelayPoint]:  # noqa: D102
        # order 1: the bound grows with the delay (tau^2 R for constant delays), so the upper
        # ends suffice
        return box_vertices(m) if self.order == 2 else [(True,) * m]

    def positivity(  # noqa: D102
        self, var: Mapping[str, Any], ch: Channels, mu: float | None
    ) -> list[MatrixInequality]:
        out = [MatrixInequality("P", var["P"], normalise=True)]
        for i, r in enumerate(ch.r):
            names = [f"Q{i}", f"Qa{i}", f"Ra{i}"] if self._interval(i, mu) else [f"Q{i}"]
            if self._slow(mu):
                names.append(f"U{i}")
            out += [MatrixInequality(name, var[name], normalise=True) for name in names]
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
            c, low = ch.coef(i), self.lower_bound(i)
            ends = [("x", c), (f"d{i}", 1.0)] if mu == 0.0 else [("x", c), (f"b{i}", 1.0)]
            if self._interval(i, mu):
                ends.insert(1, (f"a{i}", 1.0))
                _add_chain(phi, ends[:2], var[f"Qa{i}"])
                phi.add_quad({"dx": c}, low * low * var[f"Ra{i}"])
                for weight, form in zip(_LEGENDRE_WEIGHTS, self._legendre(
                        ("x", c), f"a{i}", f"u{i}"), strict=False):
                    phi.add_quad(form, -weight * var[f"Ra{i}"])
            _add_chain(phi, ends[-2:], var[f"Q{i}"])
            if self._slow(mu):
                phi.add_quad({"x": c}, var[f"U{i}"])
                phi.add_quad({f"d{i}": 1.0}, -(1.0 - float(mu or 0.0)) * var[f"U{i}"])
            if mu != 0.0:  # (h - l) int_{-h}^{-l} int y'^T R y'
                phi.add_quad({"dx": c}, _span_sq(h[i], h2[i], low) * var[f"R{i}"])
            elif point[i] or low > 0.0:  # tau int_{-tau}^0 int y'^T R y' at tau = h or l
                phi.add_quad({"dx": c}, (h2[i] if point[i] else low * low) * var[f"R{i}"])
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

    def _top(self, ch: Channels, i: int, mu: float | None) -> tuple[str, Any]:
        """Upper end of the interval the delay moves in: ``y_i(t)`` or ``a_i = y_i(t - l_i)``."""
        return (f"a{i}", 1.0) if self._interval(i, mu) else ("x", ch.coef(i))

    def _segments(self, ch: Channels, i: int, mu: float | None) -> list[list[Form]]:
        """Forms entering the integral bound, per sub-interval (one or two)."""
        first = self._legendre(self._top(ch, i, mu), f"d{i}", f"v{i}")
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
        """Add the derivative of ``z^T P z`` (``z`` augmented by signal integrals if order 2).

        Each integral over an interval the delay splits is ``(tau - l) v + (h - tau) w``, which
        is ``(h - l) v`` at ``tau = h`` and ``(h - l) w`` at ``tau = l``.
        """
        if self.order == 1:
            phi.add_he({"x": 1.0}, var["P"], {"dx": 1.0})
            return
        z: list[Form] = [{"x": 1.0}]
        dz: list[Form] = [{"dx": 1.0}]
        for i, hi in enumerate(h):
            top, low = self._top(ch, i, mu), self.lower_bound(i)
            if self._interval(i, mu):
                z.append({f"u{i}": low})
                dz.append({"x": ch.coef(i), f"a{i}": -1.0})
            span = hi - low if low else hi
            if mu == 0.0:
                z.append({f"v{i}": hi} if point[i] else {f"v{i}": low} if low else {})
                dz.append({"x": ch.coef(i), f"d{i}": -1.0})
            else:
                z.append({f"v{i}": span} if point[i] else {f"w{i}": span})
                dz.append({top[0]: top[1], f"b{i}": -1.0})
        p = var["P"]
        cuts = np.cumsum([0, ch.n, *(block for i, r in enumerate(ch.r)
                                     for block in ([r, r] if self._interval(i, mu) else [r]))])
        for a, za in enumerate(z):
            for b, zb in enumerate(dz):
                phi.add_he(za, p[cuts[a] : cuts[a + 1], cuts[b] : cuts[b + 1]], zb)

    def _add_integral_bound(
        self, phi: BlockMatrix, var: Mapping[str, Any], ch: Channels, i: int, mu: float | None
    ) -> None:
        """Subtract the lower bound of ``(h_i - l_i) int y_i'^T R_i y_i'`` over the interval."""
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


def _add_chain(phi: BlockMatrix, ends: list[tuple[str, Any]], q: Any) -> None:
    """Derivative of ``int_{t - b}^{t - a} y^T Q y``: ``Q`` at the upper end minus at the lower."""
    (top, c_top), (bottom, c_bottom) = ends
    phi.add_quad({top: c_top}, q)
    phi.add_quad({bottom: c_bottom}, -q)


def _span_sq(h: Any, h2: Any, low: float) -> Any:
    """``(h - l)^2`` as ``h^2 - 2 l h + l^2``: affine in the parameters ``h`` and ``h^2`` (DPP)."""
    return h2 - 2.0 * low * h + low * low if low else h2


JENSEN = LyapunovKrasovskii("jensen", order=1, reciprocal=False)
RECIPROCAL = LyapunovKrasovskii("rcc", order=1, reciprocal=True)
WIRTINGER = LyapunovKrasovskii("wirtinger", order=2, reciprocal=True)
