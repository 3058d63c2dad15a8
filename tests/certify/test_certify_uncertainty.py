"""Affine parameters certified by full-block multipliers instead of vertex enumeration."""

from __future__ import annotations

import dataclasses
import itertools

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

ZERO = np.zeros((2, 2))
# the benchmark's A0[0, 0] and Ad[1, 0] as parameters (each a rank-one change)
DIRECTIONS = (
    Direction(np.array([[1.0, 0.0], [0.0, 0.0]]), (ZERO,)),
    Direction(ZERO, (np.array([[0.0, 0.0], [1.0, 0.0]]),)),
)


def _family(benchmark_system, points, variation="switching") -> PolytopicDelaySystem:
    return PolytopicDelaySystem((benchmark_system,), variation,
                                AffineUncertainty(DIRECTIONS, np.asarray(points)))


def _box(lower, upper) -> np.ndarray:
    return np.array(list(itertools.product(*zip(lower, upper, strict=True))))


def _enumerated(family: PolytopicDelaySystem) -> PolytopicDelaySystem:
    return PolytopicDelaySystem(tuple(family.corners()), "switching")


def test_one_rank_one_parameter_is_lossless_against_its_vertices(benchmark_system):
    family = _family(benchmark_system, [[-0.5, 0.0], [0.5, 0.0]])
    robust = max_delay(family, "rcc", rtol=1e-3)
    enumerated = max_delay(_enumerated(family), "rcc", rtol=1e-3)
    assert robust == pytest.approx(enumerated, rel=5e-3)
    assert 0.5 < robust < 1.867  # a band around the nominal costs margin


def test_two_parameters_stay_below_each_corners_exact_margin(benchmark_system):
    family = _family(benchmark_system, _box([-0.3, -0.4], [0.3, 0.4]))
    robust = max_delay(family, "rcc", rtol=1e-3)
    enumerated = max_delay(_enumerated(family), "rcc", rtol=1e-3)
    exact = min(exact_constant_margin(corner) for corner in family.corners())
    assert 0.0 < robust <= enumerated * (1 + 1e-3) and robust < exact


def test_a_polygon_of_points_is_covered_at_interior_points(benchmark_system):
    rng = np.random.default_rng(3)
    triangle = np.array([[-0.5, -0.5], [0.5, -0.2], [0.0, 0.6]])
    family = _family(benchmark_system, triangle)
    bound = 0.98 * max_delay(family, "rcc", rtol=1e-3)
    for weights in rng.dirichlet(np.ones(3), size=5):
        theta = weights @ triangle
        point = benchmark_system.shifted(family.uncertainty, theta)
        assert certify_delay(point, bound, "rcc").certified


def test_parameters_that_do_not_vary_change_nothing(benchmark_system):
    moved = benchmark_system.shifted(AffineUncertainty(DIRECTIONS, [[0.2, -0.1]]), [0.2, -0.1])
    fixed = _family(benchmark_system, [[0.2, -0.1]])
    assert max_delay(fixed, "rcc", rtol=1e-3) == pytest.approx(
        max_delay(moved, "rcc", rtol=1e-3), rel=1e-6)


def test_frozen_vertices_with_parameters(benchmark_system):
    slower = LinearDelaySystem(benchmark_system.A0 - 0.5 * np.eye(2), benchmark_system.A)
    family = PolytopicDelaySystem((benchmark_system, slower), "frozen",
                                  AffineUncertainty(DIRECTIONS, _box([-0.2, 0.0], [0.2, 0.3])))
    cert = certify_delay(family, 0.8, "rcc")
    assert cert.certified and cert.verify()
    assert any(name.startswith("P@1") for name in cert.matrices)  # one functional per vertex


@pytest.mark.parametrize("method", ["jensen", "wirtinger", "io"])
def test_every_method_takes_parameters_and_verifies(benchmark_system, method):
    cert = certify_delay(_family(benchmark_system, _box([-0.2, -0.2], [0.2, 0.2])), 0.5, method)
    assert cert.certified and cert.verify()


def test_certificate_round_trips_and_a_tampered_multiplier_fails(benchmark_system):
    cert = certify_delay(_family(benchmark_system, _box([-0.3, -0.3], [0.3, 0.3])), 1.0, "rcc")
    assert cert.certified
    again = Certificate.from_json(cert.to_json())
    assert again.verify() and again.system.uncertainty is not None
    np.testing.assert_array_equal(again.system.uncertainty.points, cert.system.uncertainty.points)
    assert any("affine parameters" in a for a in again.assumptions)
    matrices = dict(cert.matrices)
    matrices["MR0@0"] = -matrices["MR0@0"]
    assert not dataclasses.replace(cert, matrices=matrices).verify()


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: AffineUncertainty((), [[0.0]]), "at least one parameter direction"),
        (lambda: AffineUncertainty(DIRECTIONS, [[0.0, np.nan]]), "NaN or inf"),
        (lambda: AffineUncertainty(DIRECTIONS, [[0.0, 0.0, 0.0]]), "points must have shape"),
        (lambda: AffineUncertainty(DIRECTIONS, [[0.0, 0.0]], ("a",)), "1 names for 2"),
        (lambda: Direction(np.ones((2, 3)), ()), "must be square"),
        (lambda: Direction(ZERO, (np.ones((3, 3)),)), "expected (2, 2)"),
        (lambda: PolytopicDelaySystem(
            (LinearDelaySystem(np.eye(3), (np.eye(3),)),), "switching",
            AffineUncertainty(DIRECTIONS, [[0.0, 0.0]])), "the vertices have n=3"),
        (lambda: PolytopicDelaySystem(
            (LinearDelaySystem(np.eye(2), (np.eye(2),)),), "switching",
            AffineUncertainty((Direction(ZERO, (ZERO,), -np.eye(2)),), [[1.0]])), "singular"),
    ],
)
def test_bad_uncertainties_raise_one_line_errors(build, message):
    with pytest.raises(ValueError, match=None) as info:
        build()
    assert message in str(info.value) and "\n" not in str(info.value)
