"""Input-output (scaled small-gain) LMI with the delay-integral operator.

Each delayed signal ``y_i = C_i x`` (see :mod:`certify.channels`) is written
``y_i(t - tau_i) = y_i(t) - w_i`` with ``w_i = Delta_i(y_i') = int_{t - tau_i(t)}^t y_i'``.
By Cauchy–Schwarz the operator ``Delta_i`` has L2 gain at most ``h_i`` for *any* time
variation of ``tau_i(t)`` in ``[0, h_i]`` (Kao & Lincoln 2004; Fridman & Shustin 2001), and
it acts identically on every component, so it commutes with any constant matrix: a full
positive scaling ``X_i`` is sound. The loop
``E x' = (A0 + sum_i A_i) x - sum_i B_i w_i`` (``A_i = B_i C_i``) is stable if the
bounded-real (KYP) inequality

``d/dt (x^T P x) + sum_i (h_i^2 y_i'^T X_i y_i' - w_i^T X_i w_i) < 0``

holds, written in descriptor/Finsler form so that it is affine in ``(E, A0, A_i)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from certify.blocks import BlockMatrix, Form, MatrixInequality
from certify.channels import Channels
from certify.conditions import DelayPoint, LMIMethod, VariableSpec
from certify.system import LinearDelaySystem
from certify.uncertainty import Direction

__all__ = ["SMALL_GAIN", "ScaledSmallGain"]


class ScaledSmallGain(LMIMethod):
    """Scaled small-gain certificate with one full scaling per delay channel."""

    name = "io"

    def blocks(self, ch: Channels, mu: float | None) -> dict[str, int]:  # noqa: D102
        return {"x": ch.n, "dx": ch.n} | {f"w{i}": r for i, r in enumerate(ch.r)}

    def functional_variables(  # noqa: D102
        self, ch: Channels, mu: float | None
    ) -> list[VariableSpec]:
        return [VariableSpec("P", (ch.n, ch.n), True)] + [
            VariableSpec(f"X{i}", (r, r), True) for i, r in enumerate(ch.r)
        ]

    def delay_points(self, m: int, mu: float | None) -> list[DelayPoint]:  # noqa: D102
        return [(True,) * m]

    def positivity(  # noqa: D102
        self, var: Mapping[str, Any], ch: Channels, mu: float | None
    ) -> list[MatrixInequality]:
        names = ["P"] + [f"X{i}" for i in range(ch.m)]
        return [MatrixInequality(k, var[k], normalise=True) for k in names]

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
        phi.add_he({"x": 1.0}, var["P"], {"dx": 1.0})
        for i in range(ch.m):
            phi.add_quad({"dx": ch.coef(i)}, h2[i] * var[f"X{i}"])
            phi.add_quad({f"w{i}": 1.0}, -var[f"X{i}"])
        return phi

    def dynamics(self, vertex: LinearDelaySystem | Direction, ch: Channels) -> Form:  # noqa: D102
        form: dict[str, Any] = {"x": vertex.A0 + sum(vertex.A), "dx": -vertex.E_matrix}
        form.update({f"w{i}": -ch.input_matrix(vertex, i) for i in range(ch.m)})
        return form

    def assumptions(self, mu: float | None) -> list[str]:  # noqa: D102
        note = "" if mu is None else "; the derivative bound mu is not used"
        if any(self.lower):
            note += "; the lower delay bounds are not used (it covers every tau_i in [0, h_i])"
        return [
            "scaled small gain: ||int_{t-tau_i}^t v|| <= h_i ||v|| in L2 for any delay "
            f"variation, full scaling per channel{note}"
        ]


SMALL_GAIN = ScaledSmallGain()
