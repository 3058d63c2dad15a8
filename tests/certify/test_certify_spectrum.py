from __future__ import annotations

import math

import numpy as np
import pytest

from certify import (
    LinearDelaySystem,
    PolytopicDelaySystem,
    exact_constant_margin,
    rightmost_roots,
    spectral_abscissa,
    stability_intervals,
)

BENCHMARK_EXACT = 6.172581371  # arccos(-0.9) / sqrt(0.19)


def _char_residual(sys: LinearDelaySystem, tau: list[float], lam: complex) -> float:
    t = (
        lam * sys.E_matrix
        - sys.A0
        - sum(a * np.exp(-lam * ti) for a, ti in zip(sys.A, tau, strict=True))
    )
    return float(np.linalg.svd(t, compute_uv=False)[-1])


def test_scalar_rightmost_root_is_lambert_w(scalar_system):
    roots = rightmost_roots(scalar_system, 1.0, k=4)
    # principal branch W0(-1) = -0.3181315052 + 1.3372357014j
    assert roots[0].real == pytest.approx(-0.3181315052, abs=1e-9)
    assert abs(roots[0].imag) == pytest.approx(1.3372357014, abs=1e-9)
    assert np.all(np.diff(roots.real) <= 1e-12)


def test_roots_solve_characteristic_equation(benchmark_system):
    tau = [2.5]
    for lam in rightmost_roots(benchmark_system, tau, k=6):
        assert _char_residual(benchmark_system, tau, lam) < 1e-10


def test_multi_delay_roots():
    sys = LinearDelaySystem(-np.eye(2), [np.array([[0.0, 0.5], [-0.5, 0.0]]), -0.4 * np.eye(2)])
    tau = [0.7, 2.1]
    roots = rightmost_roots(sys, tau, k=5)
    assert len(roots) == 5
    assert max(_char_residual(sys, tau, lam) for lam in roots) < 1e-10


@pytest.mark.parametrize("a", [1.0, 2.0, 0.5])
def test_scalar_exact_margin(a):
    assert exact_constant_margin(LinearDelaySystem(0.0, [-a])) == pytest.approx(
        math.pi / (2 * a), abs=1e-9
    )


def test_benchmark_exact_margin(benchmark_system):
    margin = exact_constant_margin(benchmark_system)
    assert margin == pytest.approx(math.acos(-0.9) / math.sqrt(0.19), abs=1e-9)
    assert margin == pytest.approx(BENCHMARK_EXACT, abs=1e-6)
    assert spectral_abscissa(benchmark_system, 0.999 * margin) < 0
    assert spectral_abscissa(benchmark_system, 1.001 * margin) > 0
    assert abs(spectral_abscissa(benchmark_system, margin)) < 1e-9


def test_common_delay_margin_with_split_channels(benchmark_system):
    half = 0.5 * benchmark_system.A[0]
    split = LinearDelaySystem(benchmark_system.A0, [half, half])
    assert exact_constant_margin(split) == pytest.approx(BENCHMARK_EXACT, abs=1e-6)


def test_descriptor_form_gives_same_spectrum(benchmark_system):
    e = np.array([[2.0, 1.0], [0.0, 0.5]])
    desc = LinearDelaySystem(e @ benchmark_system.A0, [e @ benchmark_system.A[0]], E=e)
    np.testing.assert_allclose(
        rightmost_roots(desc, 3.0, k=4), rightmost_roots(benchmark_system, 3.0, k=4), atol=1e-9
    )
    assert exact_constant_margin(desc) == pytest.approx(BENCHMARK_EXACT, abs=1e-6)


def test_delay_independent_and_unstable_cases():
    assert exact_constant_margin(LinearDelaySystem(-2.0, [1.0])) == math.inf
    assert exact_constant_margin(LinearDelaySystem(1.0, [-0.5])) == 0.0


def test_structural_zero_root_can_be_excluded():
    # consensus pair: x1' = x2(t - tau) - x1, x2' = x1(t - tau) - x2 has a root at 0 for all tau
    sys = LinearDelaySystem(-np.eye(2), [np.array([[0.0, 1.0], [1.0, 0.0]])])
    assert abs(spectral_abscissa(sys, 1.0)) < 1e-12
    assert spectral_abscissa(sys, 1.0, exclude_zero=True) < 0
    assert exact_constant_margin(sys) == 0.0
    assert exact_constant_margin(sys, exclude_zero=True) == math.inf


def test_spectral_input_errors(benchmark_system):
    with pytest.raises(ValueError, match="delays"):
        spectral_abscissa(benchmark_system, [-1.0])
    with pytest.raises(ValueError, match="expected 1 delays"):
        rightmost_roots(benchmark_system, [1.0, 2.0])
    with pytest.raises(ValueError, match="single LinearDelaySystem"):
        exact_constant_margin(PolytopicDelaySystem((benchmark_system,)))


# Gu, Kharitonov & Chen (2003), p. 193: x'' - 0.1 x' + 2 x = x(t - tau), stable only for
# tau in (0.100174, 1.71785) (unstable without delay).
DELAY_STABILISED = LinearDelaySystem(np.array([[0.0, 1.0], [-2.0, 0.1]]),
                                     [np.array([[0.0, 0.0], [1.0, 0.0]])])


def _analytic_crossings() -> list[float]:
    """First crossing delay of each frequency: |2 - w^2 - 0.1 j w| = 1, phase gives tau."""
    taus = []
    for w2 in np.roots([1.0, -3.99, 3.0]):
        w = math.sqrt(w2)
        taus.append(float(np.mod(-np.angle(2.0 - w2 - 0.1j * w), 2 * math.pi) / w))
    return sorted(taus)


def test_stability_interval_not_containing_zero():
    (low, high), = stability_intervals(DELAY_STABILISED, 5.0)
    np.testing.assert_allclose([low, high], _analytic_crossings(), rtol=1e-9)
    assert low == pytest.approx(0.100174, abs=1e-5)
    assert high == pytest.approx(1.71785, abs=1e-5)
    assert spectral_abscissa(DELAY_STABILISED, 0.0) > 0
    assert spectral_abscissa(DELAY_STABILISED, 1.0) < 0


def test_margin_from_a_minimum_delay():
    low, high = _analytic_crossings()
    assert exact_constant_margin(DELAY_STABILISED) == 0.0
    assert exact_constant_margin(DELAY_STABILISED, 0.9 * low) == 0.0
    assert exact_constant_margin(DELAY_STABILISED, 0.5) == pytest.approx(high, rel=1e-9)
    assert exact_constant_margin(DELAY_STABILISED, 1.1 * high) == 0.0


def test_intervals_of_a_system_stable_without_delay(benchmark_system):
    intervals = stability_intervals(benchmark_system, 10.0)
    assert intervals == [(0.0, pytest.approx(BENCHMARK_EXACT, abs=1e-6))]
    assert stability_intervals(LinearDelaySystem(-2.0, [1.0]), 3.0) == [(0.0, 3.0)]
    assert stability_intervals(LinearDelaySystem(1.0, [-0.5]), 3.0) == []


def test_margin_from_lower_on_a_stable_system(benchmark_system):
    assert exact_constant_margin(benchmark_system, 2.0) == pytest.approx(BENCHMARK_EXACT, abs=1e-6)
    assert exact_constant_margin(benchmark_system, 7.0) == 0.0
    with pytest.raises(ValueError, match="lower must be a finite delay >= 0"):
        exact_constant_margin(benchmark_system, -1.0)
    with pytest.raises(ValueError, match="h_max must be finite and positive"):
        stability_intervals(benchmark_system, 0.0)
