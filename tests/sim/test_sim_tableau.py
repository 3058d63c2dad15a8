"""The simulator's Runge–Kutta method has the order and stability it claims."""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest
from scipy.optimize import brentq

from teleopkit.sim import tableau

A, B = tableau.A, tableau.B
C = np.array(tableau.C)


def _order_conditions() -> list[tuple[str, float, float]]:
    """The 17 conditions of order five: ``B . Phi(tree) = 1 / gamma(tree)`` per rooted tree."""
    c2, c3, c4 = C**2, C**3, C**4
    ac, ac2, ac3 = A @ C, A @ c2, A @ c3
    return [
        ("b.1", B.sum(), 1.0),
        ("b.c", B @ C, 1 / 2),
        ("b.c^2", B @ c2, 1 / 3), ("b.Ac", B @ ac, 1 / 6),
        ("b.c^3", B @ c3, 1 / 4), ("b.(c Ac)", B @ (C * ac), 1 / 8),
        ("b.Ac^2", B @ ac2, 1 / 12), ("b.AAc", B @ (A @ ac), 1 / 24),
        ("b.c^4", B @ c4, 1 / 5), ("b.(c^2 Ac)", B @ (c2 * ac), 1 / 10),
        ("b.(c Ac^2)", B @ (C * ac2), 1 / 15), ("b.(c AAc)", B @ (C * (A @ ac)), 1 / 30),
        ("b.(Ac)^2", B @ (ac * ac), 1 / 20), ("b.Ac^3", B @ ac3, 1 / 20),
        ("b.A(c Ac)", B @ (A @ (C * ac)), 1 / 40), ("b.AAc^2", B @ (A @ ac2), 1 / 60),
        ("b.AAAc", B @ (A @ (A @ ac)), 1 / 120),
    ]


@pytest.mark.parametrize(("name", "value", "expected"), _order_conditions())
def test_every_condition_of_order_five_holds(name, value, expected):
    assert value == pytest.approx(expected, rel=1e-14, abs=1e-15), name


def test_explicit_consistent_and_on_the_input_grid():
    assert np.all(np.triu(A) == 0.0)  # explicit
    np.testing.assert_allclose(A.sum(axis=1), C, atol=1e-15)  # stage times are the row sums
    assert tableau.STAGES == len(B) == len(C) == A.shape[0]
    assert tableau.ROWS == tuple(int(r) for r in C * tableau.ROWS_PER_STEP)
    np.testing.assert_array_equal(np.array(tableau.ROWS) / tableau.ROWS_PER_STEP, C)
    assert C[0] == 0.0 and C[-1] == 1.0  # the last stage's time is the next step's first


def test_not_of_order_six():
    """The tall tree's condition of order six fails (``b A^4 c = 1/640``, not ``1/720``)."""
    assert B @ np.linalg.matrix_power(A, 4) @ C == pytest.approx(1 / 640, rel=1e-12)


def _stability(z: float) -> float:
    return 1.0 + z * B @ np.linalg.solve(np.eye(tableau.STAGES) - z * A, np.ones(tableau.STAGES))


def test_stability_function_and_real_limit():
    """``R(z) = sum_{k <= 5} z^k / k! + z^6 / 640``, stable on the real axis down to -3.39."""
    for z in (-3.0, -1.0, 0.5):
        taylor = sum(z**k / factorial(k) for k in range(6))
        assert _stability(z) == pytest.approx(taylor + z**6 / 640, rel=1e-12)
    limit = brentq(lambda z: _stability(z) - 1.0, -4.0, -2.0)
    assert limit == pytest.approx(-3.3865, abs=1e-4)
    assert all(abs(_stability(z)) < 1.0 for z in np.linspace(-3.38, -1e-3, 200))
