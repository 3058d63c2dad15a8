"""The kernel's polynomial sine and cosine against libm."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from teleopkit.sim.trig import sincos


@njit(cache=True)
def _both(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    sin, cos = np.empty_like(x), np.empty_like(x)
    for i in range(x.size):
        sin[i], cos[i] = sincos(x[i])
    return sin, cos


def _ulps(got: np.ndarray, expected: np.ndarray) -> np.ndarray:
    return np.abs(got - expected) / np.spacing(np.abs(expected))


def test_within_two_ulp_of_libm_below_1e5():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-4.0, 4.0, 200_000), rng.uniform(-1e5, 1e5, 200_000),
                        np.arange(-64, 65) * (math.pi / 4), [0.0, -0.0, 1e-300, 5e-324]])
    sin, cos = _both(x)
    assert _ulps(sin, np.sin(x)).max() <= 2.0
    assert _ulps(cos, np.cos(x)).max() <= 2.0


def test_odd_even_and_periodic():
    x = np.linspace(0.0, 10.0, 1001)
    sin, cos = _both(x)
    minus_sin, minus_cos = _both(-x)
    np.testing.assert_array_equal(minus_sin, -sin)
    np.testing.assert_array_equal(minus_cos, cos)
    np.testing.assert_allclose(sin**2 + cos**2, 1.0, rtol=0, atol=4e-16)
