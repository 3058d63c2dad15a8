"""Safety layer: exact, total projection onto a certified gain polytope."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from teleopkit.certification import certify_gains
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.model.params import paper_setup
from teleopkit.safety import Fallback
from teleopkit.safety.factory import layer_for
from teleopkit.safety.polytope import PolytopeLayer

SETTINGS = settings(deadline=None, max_examples=200,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])
REFERENCE = settings(SETTINGS, max_examples=50)

CERT = certify_gains(paper_setup(), GainBox.uniform((1.0, 50.0), (1.0, 150.0)), 1.0, 1.0)
LAYER = layer_for(CERT)
STEP = np.array([0.5, 0.5, 2.0, 2.0])
RATE_LAYER = PolytopeLayer(CERT.polytope, max_step=STEP)

gains = st.floats(-100.0, 300.0, allow_nan=False, allow_infinity=False)
actions = arrays(np.float64, 4, elements=gains)
wild = arrays(np.float64, 4, elements=st.one_of(
    gains, st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300])))
weights = st.floats(0.0, 1.0)


def inside(action: np.ndarray) -> bool:
    return bool(CERT.polytope.contains(action, tol=1e-9))


def member(draw_weights: list[float]) -> np.ndarray:
    """A point of the set: convex combination of the polytope's vertices."""
    vertices = CERT.polytope.vertices()
    w = np.asarray(draw_weights[:len(vertices)]) + 1e-3
    return (w / w.sum()) @ vertices


members = st.lists(weights, min_size=16, max_size=16).map(member)


@SETTINGS
@given(actions)
def test_projection_lies_in_the_set(raw):
    result = LAYER.project(raw)
    assert inside(result.action)
    assert result.fallback == Fallback.NONE
    assert result.distance == pytest.approx(np.linalg.norm(result.action - raw), abs=1e-12)


@SETTINGS
@given(actions)
def test_projection_is_idempotent(raw):
    once = LAYER.project(raw).action
    np.testing.assert_allclose(LAYER.project(once).action, once, rtol=0, atol=1e-12)


@SETTINGS
@given(actions, actions)
def test_projection_is_non_expansive(x, y):
    px, py = LAYER.project(x).action, LAYER.project(y).action
    assert np.linalg.norm(px - py) <= np.linalg.norm(x - y) + 1e-12


@SETTINGS
@given(members)
def test_points_of_the_set_stay(point):
    result = LAYER.project(point)
    np.testing.assert_array_equal(result.action, point)
    assert result.distance == 0.0


@REFERENCE
@given(actions)
@example(np.array([76.0, 118.0, 118.0, 118.0]))  # onto vertices: Clarabel stalled with
@example(np.array([144.0, 0.0, 131.0, 0.0]))  # equilibration (first) or without it (second)
def test_fast_path_matches_cvxpy_reference(raw):
    np.testing.assert_allclose(LAYER.project(raw).action, LAYER.project_qp(raw),
                               rtol=0, atol=1e-7)


@REFERENCE
@given(actions, members)
def test_rate_bounded_path_matches_cvxpy_reference(raw, prev):
    result = RATE_LAYER.project(raw, prev)
    assert result.fallback == Fallback.NONE
    np.testing.assert_allclose(result.action, RATE_LAYER.project_qp(raw, prev),
                               rtol=0, atol=1e-7)


@SETTINGS
@given(actions, members)
def test_rate_bound_is_respected(raw, prev):
    result = RATE_LAYER.project(raw, prev)
    assert inside(result.action)
    assert np.all(np.abs(result.action - prev) <= STEP + 1e-9)
    at_bound = np.abs(np.abs(result.action - prev) - STEP) <= 1e-9
    np.testing.assert_array_equal(result.rate_active, at_bound)


@SETTINGS
@given(wild, st.one_of(st.none(), wild))
def test_non_finite_input_never_escapes(raw, prev):
    for layer in (LAYER, RATE_LAYER):
        result = layer.project(raw, prev)
        assert np.all(np.isfinite(result.action)) and inside(result.action)
        assert bool(result.fallback & Fallback.NONFINITE_INPUT) == (not np.all(np.isfinite(raw)))


def test_fallback_is_the_projected_previous_action_or_the_interior_point():
    prev = np.array([40.0, 10.0, 60.0, 30.0])
    held = LAYER.project(np.array([np.nan, 1.0, 1.0, 1.0]), prev)
    np.testing.assert_array_equal(held.action, LAYER.project(prev).action)
    assert held.fallback == Fallback.NONFINITE_INPUT and held.distance == np.inf
    centre = LAYER.project(np.full(4, np.inf))
    np.testing.assert_array_equal(centre.action, LAYER.fallback_action)
    assert np.all(CERT.polytope.G @ LAYER.fallback_action < CERT.polytope.h)  # interior


def test_empty_rate_box_falls_back_to_the_polytope_and_says_so():
    prev = np.array([60.0, 10.0, 20.0, 30.0])  # outside the set, rate box misses it on joint 1
    result = RATE_LAYER.project(np.array([60.0, 10.0, 20.0, 30.0]), prev)
    assert result.fallback == Fallback.RATE_INFEASIBLE
    np.testing.assert_allclose(result.action, LAYER.project(prev).action, atol=1e-12)
    nan_prev = RATE_LAYER.project(np.array([10.0, 10.0, 30.0, 30.0]), np.full(4, np.nan))
    assert nan_prev.fallback == Fallback.RATE_INFEASIBLE and inside(nan_prev.action)


def test_active_constraints_are_reported():
    result = LAYER.project(np.array([40.0, 10.0, 60.0, 30.0]))
    assert LAYER.active_labels(result.active) == (CERT.polytope.labels[8],)
    assert "Nuño joint 1" in CERT.polytope.labels[8]
    corner = LAYER.project(np.array([100.0, 10.0, 500.0, 30.0]))
    assert set(LAYER.active_labels(corner.active)) == {"K_r1 <= max", "B_r1 <= max"}
    assert not LAYER.project(np.array([10.0, 10.0, 30.0, 30.0])).active.any()


@settings(SETTINGS, max_examples=20)
@given(arrays(np.float64, (64, 4), elements=st.one_of(gains, st.just(np.nan))),
       arrays(np.float64, (64, 4), elements=gains))
def test_batch_equals_single_samples(raw, prev):
    for layer in (LAYER, RATE_LAYER):
        batch = layer.project_batch(raw, prev)
        for b in range(len(raw)):
            single = layer.project(raw[b], prev[b])
            np.testing.assert_array_equal(batch.action[b], single.action)
            np.testing.assert_array_equal(batch.active[b], single.active)
            assert batch.fallback[b] == single.fallback
            assert batch.distance[b] == single.distance


@st.composite
def polygon_polytopes(draw):
    """Random two-joint polytopes: a box cut by up to three random half-planes per joint, all
    through the slack of a chosen interior point."""
    normals, offsets = [], []
    for joint in range(2):
        centre = np.array([draw(st.floats(5.0, 45.0)), draw(st.floats(5.0, 140.0))])
        for _ in range(draw(st.integers(0, 3))):
            angle = draw(st.floats(0.0, 2 * np.pi))
            g = np.zeros(4)
            g[[joint, 2 + joint]] = np.cos(angle), np.sin(angle)
            normals.append(g)
            offsets.append(g[[joint, 2 + joint]] @ centre + draw(st.floats(0.5, 30.0)))
    box = GainPolytope.from_box(GainBox.uniform((0.0, 50.0), (0.0, 150.0)))
    if not normals:
        return box
    return box.intersect(np.array(normals), np.array(offsets), tuple(f"cut {i}" for i in
                                                                     range(len(offsets))))


@settings(SETTINGS, max_examples=25)
@given(polygon_polytopes(), actions)
def test_random_polygons_match_the_reference(polytope, raw):
    layer = PolytopeLayer(polytope)
    result = layer.project(raw)
    assert polytope.contains(result.action, tol=1e-9)
    np.testing.assert_allclose(result.action, layer.project_qp(raw), rtol=0, atol=1e-7)


def test_the_reference_is_exact_far_from_the_set():
    """From 190 gain units away Clarabel stops 1e-4 short of a bound; the polish must still
    find the exact projection (it once kept the solver's point)."""
    box = GainPolytope.from_box(GainBox.uniform((0.0, 50.0), (0.0, 150.0)))
    cuts = np.array([[np.cos(1.0), 0.0, np.sin(1.0), 0.0], [np.cos(5.0), 0.0, np.sin(5.0), 0.0]])
    polytope = box.intersect(cuts, np.array([7.90886645, -2.37631045]), ("cut 0", "cut 1"))
    layer = PolytopeLayer(polytope)
    raw = np.array([200.0, 12.0, -1e-5, -1e-5])
    exact = layer.project(raw).action
    assert exact[3] == 0.0
    np.testing.assert_allclose(layer.project_qp(raw), exact, rtol=0, atol=1e-9)


def test_uncertified_certificate_is_refused():
    lmi = dataclasses.replace(CERT, method="lmi", certified=False, polytope_certified=False,
                              violation="LMI infeasible")
    with pytest.raises(ValueError, match="does not certify"):
        layer_for(lmi)
    layer_for(dataclasses.replace(lmi, polytope_certified=True))


def test_empty_polytope_is_refused():
    cert = certify_gains(paper_setup(), GainBox.uniform((40.0, 50.0), (1.0, 10.0)), 1.0, 1.0)
    with pytest.raises(ValueError, match="empty"):
        layer_for(cert)


def test_rate_cannot_exceed_the_certified_rate():
    rated = dataclasses.replace(CERT, method="lmi", certified=True, gain_variation="rate:50")
    layer = layer_for(rated, period=0.01)
    np.testing.assert_allclose(layer.max_step, 0.5)
    assert layer_for(rated, rate=10.0).max_step == pytest.approx(0.1)
    with pytest.raises(ValueError, match="exceeds"):
        layer_for(rated, rate=100.0)
    assert layer_for(CERT).max_step is None


def test_malformed_polytopes_are_refused():
    box = GainPolytope.from_box(GainBox.uniform((1.0, 50.0), (1.0, 150.0)))
    coupled = box.intersect(np.array([[1.0, 1.0, 0.0, 0.0]]), np.array([60.0]), ("coupled",))
    with pytest.raises(ValueError, match="couples joints"):
        PolytopeLayer(coupled)
    unbounded = GainPolytope(box.G[:4], box.h[:4], box.labels[:4])
    with pytest.raises(ValueError, match="unbounded"):
        PolytopeLayer(unbounded)
    with pytest.raises(ValueError, match="positive"):
        PolytopeLayer(box, max_step=0.0)
    with pytest.raises(ValueError, match="shape"):
        PolytopeLayer(box).project(np.zeros(3))


def test_near_ties_between_edges_are_resolved_exactly():
    """Far from the set, two candidates a micro-unit apart have equal squared distances."""
    layer = PolytopeLayer(GainPolytope.from_box(GainBox.uniform((0.0, 50.0), (0.0, 150.0))))
    raw = np.array([178.0, 1e-6, 1e-6, 1e-6])
    np.testing.assert_array_equal(layer.project(raw).action, [50.0, 1e-6, 1e-6, 1e-6])
