"""No LMI certificate may exceed the exact constant-delay margin (random systems)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from certify import (
    LinearDelaySystem,
    certify_delay,
    exact_constant_margin,
    spectral_abscissa,
)

N_SYSTEMS = 30
METHODS = ["jensen", "rcc", "wirtinger", "io"]
CLASSES = [None, 0.3, 0.0]
# the fast sweep skips the costliest combination (Wirtinger, time-varying, two delays)
# and the slowly-varying class; the slow test runs everything
FAST = [(m, mu) for m in METHODS for mu in (None, 0.0)]


def random_system(index: int) -> LinearDelaySystem:
    """Seeded random system with 2-4 states and 1-2 delays, stable at zero delay."""
    rng = np.random.default_rng(1000 + index)
    while True:
        n, m = int(rng.integers(2, 5)), int(rng.integers(1, 3))
        a0 = rng.normal(size=(n, n))
        delayed = [rng.normal(size=(n, n)) * rng.uniform(0.3, 1.2) for _ in range(m)]
        sys = LinearDelaySystem(a0, delayed)
        if spectral_abscissa(sys, 0.0) < -0.05:
            return sys


@pytest.mark.parametrize("index", range(N_SYSTEMS))
def test_no_certificate_beyond_exact_margin(index):
    sys = random_system(index)
    exact = exact_constant_margin(sys)
    if not math.isfinite(exact):
        pytest.skip("stable for every common constant delay")
    for method, mu in FAST:
        if method == "wirtinger" and mu is None and sys.m == 2:
            continue
        cert = certify_delay(sys, 1.001 * exact, method, mu)
        assert not cert.certified, (method, mu, exact)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(N_SYSTEMS))
def test_no_certificate_beyond_exact_margin_full_grid(index):
    sys = random_system(index)
    exact = exact_constant_margin(sys)
    if not math.isfinite(exact):
        pytest.skip("stable for every common constant delay")
    for method in METHODS:
        for mu in CLASSES:
            for factor in (1.001, 1.5, 3.0):
                cert = certify_delay(sys, factor * exact, method, mu)
                assert not cert.certified, (method, mu, factor, exact)
