"""The simulator's Runge–Kutta method: Butcher's six-stage method of order five.

Its stages fall on quarter steps (``c = 0, 1/4, 1/4, 1/2, 3/4, 1``), so the inputs (delays and the
operator reference) are sampled on a grid of a quarter step, two stages share a time and the last
stage's time is the next step's first: a delayed read is made at four of the six stages. Over
the paper's 40 s run (delay scales and operator gains 1, K_r = 10, B_r = 30) it is 1.4e-6 rad
from a converged solution at a 2.5 ms step (1.4e-6 to 1.8e-6 over randomised paper scenarios),
where the classical RK4 with the same number of derivative evaluations per control period
(1.67 ms) is 2.2e-5 rad away. J. C. Butcher, "On Runge-Kutta processes of high order",
J. Austral. Math. Soc. 4 (1964) 179-194; J. C. Butcher, *Numerical Methods for Ordinary
Differential Equations*, Wiley.

Its stability function is ``R(z) = sum_{k <= 5} z^k / k! + z^6 / 640``; on the negative real axis
it is stable down to ``z = -3.39`` (RK4: ``-2.79``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ORDER", "REAL_STABILITY_LIMIT", "ROWS", "ROWS_PER_STEP", "STAGES", "A", "B", "C"]

STAGES = 6
"""Derivative evaluations per step."""

ORDER = 5
"""Classical order of the method (the delayed reads' Hermite interpolation is of order four)."""

C = (0.0, 0.25, 0.25, 0.5, 0.75, 1.0)
"""Stage times, in steps after the step's start."""

A = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
              [1 / 4, 0.0, 0.0, 0.0, 0.0, 0.0],
              [1 / 8, 1 / 8, 0.0, 0.0, 0.0, 0.0],
              [0.0, -1 / 2, 1.0, 0.0, 0.0, 0.0],
              [3 / 16, 0.0, 0.0, 9 / 16, 0.0, 0.0],
              [-3 / 7, 2 / 7, 12 / 7, -12 / 7, 8 / 7, 0.0]])
"""Stage coefficients (strictly lower triangular): stage ``r`` is ``x + dt sum_j A[r, j] k_j``."""

B = np.array([7 / 90, 0.0, 32 / 90, 12 / 90, 32 / 90, 7 / 90])
"""Weights: the step is ``x + dt sum_r B[r] k_r``."""

ROWS_PER_STEP = 4
"""Input samples per step: the stage times fall on quarter steps."""

ROWS = tuple(round(ROWS_PER_STEP * c) for c in C)
"""Input row of each stage, from the step's first row."""

REAL_STABILITY_LIMIT = 3.3864
"""Length of the stability interval on the negative real axis: a step is stable on a mode
``exp(-rate t)`` while ``rate * dt`` is below it (the root of ``R(-z) = 1``, 3.38649, rounded
down)."""
