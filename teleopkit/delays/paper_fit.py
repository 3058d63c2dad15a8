"""The paper's delay: the 16-harmonic Fourier fit of its Fig. 3 and the fit's rigorous range.

``y(t) = C0 + sum_k a_k sin(2 pi k f0 t) + b_k cos(2 pi k f0 t)`` for ``k`` from 1 to 16, in
seconds; the coefficients are :data:`PAPER_C0`, :data:`PAPER_F0`, :data:`PAPER_SIN` and
:data:`PAPER_COS`.
:class:`~teleopkit.delays.profiles.FourierDelay` scales it per scenario.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["PAPER_C0", "PAPER_COS", "PAPER_DELAY_MAX", "PAPER_DELAY_MIN", "PAPER_F0", "PAPER_SIN",
           "paper_shape"]

PAPER_C0 = 0.9613462407597305
"""Constant term of the fit, in seconds."""

PAPER_F0 = 0.24299065416927243
"""Fundamental frequency of the fit, in hertz."""

PAPER_SIN = np.array([
    -0.02000659, -0.02349457, 0.00067474, 0.00159032, 0.00129016, -0.00135477, -0.00022001,
    0.00097632, 0.00021585, 0.00014519, -0.00020833, -0.00056968, -0.00031181, 0.00016964,
    0.0003376, -0.00022124,
])
"""Sine coefficients ``a_k`` of the fit (``k`` from 1 to 16), in seconds."""
PAPER_COS = np.array([
    -0.02556397, 0.00393168, -0.0052079, 0.00220769, 0.00300956, 0.00160663, -0.00018929,
    -0.00031848, -0.00019025, -0.00022222, -0.00010147, 0.00019351, -0.00030343, 0.0001225,
    0.00015061, 0.00039704,
])
"""Cosine coefficients ``b_k`` of the fit (``k`` from 1 to 16), in seconds."""


def paper_shape(t: np.ndarray) -> np.ndarray:
    """The paper's unscaled delay ``y(t)`` (seconds) at the times ``t``.

    The harmonics come from the angle-addition recurrence, two trigonometric evaluations per time
    instead of two per harmonic, compiled; equal to the direct sum to about ``1e-15`` s. The
    last evaluation is remembered: a simulator samples both channels at the same times.

    Parameters
    ----------
    t : ndarray
        Times in seconds, any shape.

    Returns
    -------
    ndarray
        ``y(t)``, the shape of ``t``.
    """
    global _LAST
    t = np.asarray(t, dtype=float)
    last = _LAST  # one read: another thread may replace it meanwhile
    if last is not None and last[0].shape == t.shape and np.array_equal(last[0], t):
        return last[1].copy()
    out = np.empty(t.shape)
    _paper_sum(t.reshape(-1), PAPER_SIN, PAPER_COS, out.reshape(-1))
    _LAST = (t.copy(), out.copy())
    return out


_LAST: tuple[np.ndarray, np.ndarray] | None = None
"""The last times given to :func:`paper_shape` and ``y`` at them (a pure function's memo)."""


_SUM_BLOCK = 256
"""Times per block of :func:`_paper_sum`."""


@njit(cache=True, error_model="numpy")
def _paper_sum(t: np.ndarray, sines: np.ndarray, cosines: np.ndarray,
               out: np.ndarray) -> None:
    """``out = C0 + sum_k (a_k sin + b_k cos)(2 pi k f0 t)`` by the angle-addition recurrence.

    The recurrence runs over harmonics in the outer loop and over a block of times in the inner
    one: the times are independent, so the inner loop vectorises instead of waiting on the
    recurrence's chain (the same operations in the same order per time as a loop over times).
    """
    omega = 2.0 * np.pi * PAPER_F0
    cos1, sin1 = np.empty(_SUM_BLOCK), np.empty(_SUM_BLOCK)  # the fundamental
    ck, sk = np.empty(_SUM_BLOCK), np.empty(_SUM_BLOCK)  # harmonic k
    for lo in range(0, t.size, _SUM_BLOCK):
        width = min(_SUM_BLOCK, t.size - lo)
        for j in range(width):
            cos1[j], sin1[j] = math.cos(omega * t[lo + j]), math.sin(omega * t[lo + j])
            ck[j], sk[j] = cos1[j], sin1[j]
            out[lo + j] = PAPER_C0
        for k in range(sines.size):
            a, b = sines[k], cosines[k]
            for j in range(width):
                out[lo + j] += a * sk[j] + b * ck[j]
                c, s = ck[j], sk[j]
                ck[j] = c * cos1[j] - s * sin1[j]
                sk[j] = s * cos1[j] + c * sin1[j]


def _paper_extremes(points: int = 20001) -> tuple[float, float]:
    """Rigorous bounds of ``y(t)``: grid extremes widened by the slope bound times half a step."""
    t = np.linspace(0.0, 1.0 / PAPER_F0, points)
    harmonics = np.arange(1, PAPER_SIN.size + 1)
    slope = 2.0 * np.pi * PAPER_F0 * float(harmonics @ (np.abs(PAPER_SIN) + np.abs(PAPER_COS)))
    shape, slack = paper_shape(t), slope * (t[1] - t[0]) / 2.0
    return float(shape.min()) - slack, float(shape.max()) + slack


PAPER_DELAY_MIN, PAPER_DELAY_MAX = _paper_extremes()
"""Rigorous lower and upper bounds of the Fourier fit of the paper's Fig. 3, about 0.9029 s and
1.0003 s (the maximum slightly above the paper's 1 s):
:class:`~teleopkit.delays.profiles.FourierDelay` divides the fit by the maximum."""
