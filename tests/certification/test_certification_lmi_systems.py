"""LMI certificates of gain sets: sound against exact spectra, never behind the closed form."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from certify import PolytopicDelaySystem, certify_delay, exact_constant_margin, max_delay
from teleopkit.certification import GainCertificate, certify_gains, load_certificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.systems import (
    CHANNELS,
    LMI_METHOD,
    gain_set_system,
    lmi_certificate,
    lmi_delay_margin,
)
from teleopkit.certification.nuno.condition import nuno_polytope
from teleopkit.model.linearize import rest_systems
from teleopkit.model.params import (
    paper_setup,
)
from teleopkit.robustness.falsification import falsify
from teleopkit.safety.factory import layer_for

WIDE = GainBox.uniform((1.0, 50.0), (1.0, 150.0), n_joints=1)
NARROW = GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1)


def _area(polytope: GainPolytope) -> float:
    return float(ConvexHull(polytope.joint_vertices(0)).volume)


@pytest.fixture(scope="module")
def wide_frozen(one_joint) -> GainCertificate:
    return certify_gains(one_joint, WIDE, 1.0, 1.0, method="lmi")


def test_frozen_lmi_set_contains_the_closed_form_set(one_joint, wide_frozen):
    closed = nuno_polytope(one_joint, WIDE, 1.0, 1.0)
    assert not wide_frozen.certified and wide_frozen.polytope_certified
    assert np.all(wide_frozen.polytope.contains(closed.vertices(), tol=1e-9))
    ratio = _area(wide_frozen.polytope) / _area(closed)
    assert ratio > 1.01, ratio
    assert "infeasible at the vertex" in (wide_frozen.violation or "")


def test_certified_polytope_is_certified_at_random_interior_points(one_joint, wide_frozen,
                                                                   rng):
    vertices = wide_frozen.polytope.vertices()
    for weights in rng.dirichlet(np.ones(len(vertices)), size=3):
        k, b = weights @ vertices
        point = GainPolytope.from_box(GainBox(((k, k),), ((b, b),)))
        assert lmi_certificate(one_joint, point, 1.0, 1.0).certified


def test_lmi_margin_beats_the_closed_form_and_stays_below_the_exact_margin(one_joint):
    lmi = certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi")
    closed = certify_gains(one_joint, NARROW, 1.0, 1.0, method="nuno")
    assert lmi.certified and closed.certified
    assert lmi.delay_margin > 1.3 * closed.delay_margin
    exact = min(exact_constant_margin(system)
                for action in GainPolytope.from_box(NARROW).vertices()
                for system in rest_systems(one_joint, action))
    assert lmi.delay_margin <= exact


def test_margin_of_an_unstable_corner_is_below_its_exact_margin():
    """Two joints at K_r = 50, B_r = 1: unstable beyond a constant delay of about 0.14 s."""
    params = paper_setup()
    corner = GainPolytope.from_box(GainBox(((50.0, 50.0),) * 2, ((1.0, 1.0),) * 2))
    system = gain_set_system(params, corner, "frozen")
    exact = [exact_constant_margin(vertex) for vertex in system.vertices]
    assert min(exact) < 0.2
    # no certificate beyond the exact margin, for the set and for each configuration alone
    assert not lmi_certificate(params, corner, 1.01 * min(exact), 1.01 * min(exact)).certified
    for vertex, bound in zip(system.vertices, exact, strict=True):
        if np.isfinite(bound):
            beyond = certify_delay(vertex, [1.01 * bound] * 2, LMI_METHOD, channels=CHANNELS)
            assert not beyond.certified
    assert lmi_certificate(params, corner, 0.5 * min(exact), 0.5 * min(exact)).certified


def test_switching_is_harder_than_frozen_and_rate_is_certified_as_switching(one_joint):
    frozen = certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi", variation="frozen")
    rate = certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi", variation="rate:5")
    assert rate.certified and rate.gain_variation == "rate:5"
    assert 0.0 < rate.delay_margin <= frozen.delay_margin
    assert any("certified as arbitrary switching" in a for a in rate.assumptions)
    layer = layer_for(rate)
    assert layer.max_step is not None


def test_all_returns_the_best_method_and_round_trips(one_joint):
    best = certify_gains(one_joint, NARROW, 1.0, 1.0, method="all")
    assert best.method == "lmi"
    again = load_certificate(best.to_json())
    assert again.polytope_certified and again.delay_margin == best.delay_margin


def test_bad_input(one_joint):
    with pytest.raises(ValueError, match="unknown method"):
        certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmj")
    with pytest.raises(ValueError, match="positive"):
        certify_gains(one_joint, NARROW, 0.0, 1.0, method="lmi")
    with pytest.raises(ValueError, match="closed form"):
        certify_gains(one_joint, NARROW, 1.0, 1.0, method="nuno", variation="switching")
    empty = nuno_polytope(one_joint, GainBox(((40.0, 50.0),), ((1.0, 5.0),)), 1.0, 1.0)
    with pytest.raises(ValueError, match="empty"):
        lmi_certificate(one_joint, empty, 1.0, 1.0)


def test_falsification_inside_the_lmi_set_never_diverges(one_joint, wide_frozen):
    report = falsify(one_joint, wide_frozen.polytope, 1.0, 1.0, batch=16, duration=10.0,
                     switching=False, seed=3)
    assert not report["diverged"].any()



def test_large_gain_sets_are_multiplier_uncertainties_not_enumerated_vertices():
    box = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
    system = gain_set_system(paper_setup(), GainPolytope.from_box(box), "frozen")
    assert len(system.vertices) == 2 and system.uncertainty is not None  # configurations only
    assert system.uncertainty.names == ("K_r1", "K_r2", "B_r1", "B_r2")
    assert len(system.uncertainty.points) == 16
    for corner, action in zip(system.corners()[:16], system.uncertainty.points, strict=True):
        expected = rest_systems(paper_setup(), action)[0]
        np.testing.assert_allclose(corner.A0, expected.A0, atol=1e-12)
        np.testing.assert_allclose(corner.A[0], expected.A[0], atol=1e-12)
    one_joint_box = GainBox(((1.0, 50.0), (10.0, 10.0)), ((1.0, 150.0), (30.0, 30.0)))
    small = gain_set_system(paper_setup(), GainPolytope.from_box(one_joint_box), "frozen")
    assert len(small.vertices) == 8 and small.uncertainty is None  # enumerated: least conservative


def test_switching_gains_are_never_certified_beyond_enumerated_vertices(one_joint):
    """On one joint the multiplier form is lossless against a common functional at every vertex."""
    polytope = GainPolytope.from_box(NARROW)
    multiplier = lmi_delay_margin(one_joint, polytope, "switching")
    systems = [s for action in polytope.vertices() for s in rest_systems(one_joint, action)]
    enumerated = max_delay(PolytopicDelaySystem(tuple(systems), "switching"), LMI_METHOD, rtol=0.02,
                           channels=CHANNELS)
    assert multiplier.margin == pytest.approx(enumerated, rel=0.03)
