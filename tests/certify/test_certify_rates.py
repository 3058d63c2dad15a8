"""Parameters with a bounded rate: a storage that depends on them (DESIGN section 4, class c)."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from certify import (
    AffineUncertainty,
    Certificate,
    Direction,
    LinearDelaySystem,
    PolytopicDelaySystem,
    certify_delay,
    exact_constant_margin,
    max_delay,
)

# Two Hurwitz matrices without a common quadratic Lyapunov function: constant parameters are
# stable, arbitrarily fast switching between them is not certified by one functional.
A_LOW = np.array([[-0.5, 1.0], [-10.0, -0.5]])
A_HIGH = np.array([[-0.5, 10.0], [-1.0, -0.5]])
DELAYED = np.array([[0.0, 0.0], [0.0, -0.05]])


def _oscillator(rate: float | None) -> PolytopicDelaySystem:
    direction = Direction(A_HIGH - A_LOW, (np.zeros((2, 2)),))
    uncertainty = AffineUncertainty((direction,), [[0.0], [1.0]], ("theta",),
                                    None if rate is None else [rate])
    return PolytopicDelaySystem((LinearDelaySystem(A_LOW, (DELAYED,)),), "switching",
                                uncertainty)


@pytest.fixture(scope="module")
def oscillator_margins() -> dict[float, float]:
    return {rate: max_delay(_oscillator(rate), "rcc", rtol=1e-3)
            for rate in (math.inf, 0.3, 0.1, 0.03, 0.0)}


def test_a_bounded_rate_certifies_what_arbitrary_switching_cannot(oscillator_margins):
    assert oscillator_margins[math.inf] == 0.0
    assert oscillator_margins[0.1] > 1.0 and oscillator_margins[0.0] > 5.0


def test_margins_shrink_as_the_rate_grows(oscillator_margins):
    margins = [oscillator_margins[r] for r in (0.0, 0.03, 0.1, 0.3, math.inf)]
    assert all(a >= b * (1 - 2e-3) for a, b in itertools.pairwise(margins))


def test_constant_parameters_stay_below_every_corners_exact_margin(benchmark_system):
    directions = (Direction(np.array([[1.0, 0.0], [0.0, 0.0]]), (np.zeros((2, 2)),)),)
    family = PolytopicDelaySystem((benchmark_system,), "switching",
                                  AffineUncertainty(directions, [[-0.6], [0.6]], rates=[0.0]))
    switching = PolytopicDelaySystem((benchmark_system,), "switching",
                                     AffineUncertainty(directions, [[-0.6], [0.6]]))
    frozen, common = max_delay(family, "rcc", rtol=1e-3), max_delay(switching, "rcc", rtol=1e-3)
    exact = min(exact_constant_margin(corner) for corner in family.corners())
    assert 0.0 < common <= frozen * (1 + 1e-3) and frozen < exact


def test_interior_constant_parameters_are_certified_on_their_own():
    certificate = certify_delay(_oscillator(0.0), 3.0, "rcc")
    assert certificate.certified
    for theta in (0.2, 0.5, 0.9):
        point = LinearDelaySystem(A_LOW + theta * (A_HIGH - A_LOW), (DELAYED,))
        assert certify_delay(point, 3.0, "rcc").certified


def test_an_infinite_rate_is_the_switching_certificate(benchmark_system):
    directions = (Direction(np.array([[1.0, 0.0], [0.0, 0.0]]), (np.zeros((2, 2)),)),)
    default = AffineUncertainty(directions, [[-0.3], [0.3]])
    explicit = AffineUncertainty(directions, [[-0.3], [0.3]], rates=[math.inf])
    certs = [certify_delay(PolytopicDelaySystem((benchmark_system,), "switching", unc), 1.0, "rcc")
             for unc in (default, explicit)]
    assert certs[0].certified and certs[1].certified
    assert set(certs[0].matrices) == set(certs[1].matrices)
    assert not any(name.startswith(("dP", "Z")) for name in certs[0].matrices)


def test_json_keeps_the_rates_and_verify_rechecks_the_storage():
    certificate = certify_delay(_oscillator(0.1), 1.0, "rcc")
    assert certificate.certified and {"dP0", "Z0"} <= set(certificate.matrices)
    assert any("|rate| <= 0.1" in text for text in certificate.assumptions)
    data = json.loads(certificate.to_json())
    assert data["uncertainty"]["rates"] == [0.1]
    again = Certificate.from_json(json.dumps(data))
    assert again.verify() and again.system.uncertainty.rates.tolist() == [0.1]
    data["uncertainty"]["rates"] = [None]  # claimed for arbitrary switching: not this proof
    assert not Certificate.from_json(json.dumps(data)).verify()
    tampered = json.loads(certificate.to_json())
    tampered["matrices"]["Z0"] = np.zeros((2, 2)).tolist()
    assert not Certificate.from_json(json.dumps(tampered)).verify()


@pytest.mark.parametrize(("rates", "match"), [
    ([-1.0], "non-negative"), ([math.nan], "non-negative"), ([1.0, 2.0], "1 non-negative"),
    (["fast"], "rates must be a real numeric"),
])
def test_bad_rates_are_one_line_errors(rates, match):
    direction = Direction(np.eye(2), (np.zeros((2, 2)),))
    with pytest.raises(ValueError, match=match) as info:
        AffineUncertainty((direction,), [[0.0], [1.0]], rates=rates)
    assert "\n" not in str(info.value)


def test_a_rate_bounded_parameter_that_leaves_the_dynamics_unchanged(benchmark_system):
    still = Direction(np.zeros((2, 2)), (np.zeros((2, 2)),))
    family = PolytopicDelaySystem((benchmark_system,), "switching",
                                  AffineUncertainty((still,), [[0.0], [1.0]], rates=[1.0]))
    certificate = certify_delay(family, 1.0, "rcc")
    assert certificate.certified and certificate.verify() and "dP0" in certificate.matrices
    assert certify_delay(family, 1.9, "rcc").certified is False  # RCC alone reaches 1.867
