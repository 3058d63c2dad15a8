"""Badly scaled states: the LMIs are retried in balanced (power-of-two) coordinates."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from certify import Certificate, PolytopicDelaySystem, certify_delay, max_delay
from certify.methods import get_method
from certify.solve import LMIProblem


@pytest.fixture
def badly_scaled(benchmark_system) -> PolytopicDelaySystem:
    """The benchmark in coordinates whose first state is 2^16 times the second."""
    return PolytopicDelaySystem((benchmark_system,)).scaled([2.0**16, 1.0])


def test_scaling_is_an_exact_similarity(benchmark_system, badly_scaled):
    back = badly_scaled.scaled([2.0**-16, 1.0]).vertices[0]
    np.testing.assert_array_equal(back.A0, benchmark_system.A0)
    np.testing.assert_array_equal(back.A[0], benchmark_system.A[0])
    assert set(np.log2(badly_scaled.balancing())) <= set(range(-64, 65))  # powers of two


def test_a_badly_scaled_system_is_certified_in_balanced_coordinates(badly_scaled):
    problem = LMIProblem(badly_scaled, get_method("rcc"), None)
    _, _, residuals = problem._forms[0].solve((1.0,))
    assert not residuals or min(residuals.values()) < 1e-9  # fails as given
    cert = problem.solve([1.0])
    assert cert.certified and cert.scaling and cert.verify()
    assert any("scaled by powers of two" in a for a in cert.assumptions)
    again = Certificate.from_json(cert.to_json())
    assert again.verify() and again.scaling == cert.scaling
    assert not dataclasses.replace(cert, scaling=(1.0, 1.0)).verify()
    assert not dataclasses.replace(cert, scaling=(-1.0, 1.0)).verify()


def test_balancing_does_not_change_margins(benchmark_system, badly_scaled):
    assert max_delay(badly_scaled, "rcc", rtol=1e-3) == pytest.approx(
        max_delay(benchmark_system, "rcc", rtol=1e-3), rel=2e-3)


def test_well_scaled_certificates_carry_no_scaling(benchmark_system):
    assert certify_delay(benchmark_system, 1.0, "rcc").scaling == ()


def test_retry_accurate_skips_balancing_after_an_inaccurate_solve(badly_scaled):
    raw_status = LMIProblem(badly_scaled, get_method("rcc"), None)._forms[0].solve((1.0,))[0]
    assert raw_status != "optimal"  # the case the rule is about: not solved accurately
    assert certify_delay(badly_scaled, 1.0, "rcc", retry="always").certified
    assert not certify_delay(badly_scaled, 1.0, "rcc", retry="accurate").certified


def test_retry_must_be_known(benchmark_system):
    with pytest.raises(ValueError, match="retry must be one of"):
        certify_delay(benchmark_system, 1.0, "rcc", retry="sometimes")
