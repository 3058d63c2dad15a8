"""Gain boxes, gain polytopes and the closed-form (Nuño) condition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleopkit.certification import load_certificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope, parse_range
from teleopkit.certification.nuno.condition import nuno_delay_margin, nuno_polytope, nuno_slack
from teleopkit.model.params import paper_setup

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))


@pytest.mark.parametrize(("text", "expected"), [("1:50", (1.0, 50.0)), ("7", (7.0, 7.0)),
                                                ("0:0.5", (0.0, 0.5))])
def test_parse_range(text, expected):
    assert parse_range(text, "--kr") == expected


@pytest.mark.parametrize(("text", "message"), [
    ("50:1", "inverted"), ("-1:5", "non-negative"), ("nan:5", "finite"), ("1:inf", "finite"),
    ("a:b", "numbers"), ("1:2:3", "MIN:MAX"), ("", "numbers"),
])
def test_bad_ranges(text, message):
    with pytest.raises(ValueError, match=message):
        parse_range(text, "--kr")


def test_closed_form_matches_the_formula(rng):
    params = paper_setup()
    actions = rng.uniform(0, 100, size=(100, 4))
    slack = nuno_slack(params, actions, 0.7, 0.4)
    expected = 4 * 10.0 * actions[:, 2:] - (0.7 + 0.4) ** 2 * 25.0 * actions[:, :2]
    np.testing.assert_allclose(slack, expected)


def test_polytope_is_box_and_half_planes(rng):
    params = paper_setup()
    polytope = nuno_polytope(params, BOX, 1.0, 1.0)
    actions = rng.uniform(0, 160, size=(5000, 4))
    in_box = np.all((actions >= BOX.lower) & (actions <= BOX.upper), axis=1)
    satisfied = np.all(nuno_slack(params, actions, 1.0, 1.0) >= 1e-6, axis=1)
    np.testing.assert_array_equal(polytope.contains(actions, tol=0.0), in_box & satisfied)
    vertices = polytope.joint_vertices(0)
    np.testing.assert_allclose(vertices, [[1, 2.5], [50, 125], [50, 150], [1, 150]], atol=1e-6)
    assert polytope.vertices().shape == (16, 4)
    assert np.all(polytope.contains(polytope.vertices(), tol=1e-9))


def test_delay_margin_is_the_largest_certified_bound():
    params = paper_setup()
    margin = nuno_delay_margin(params, BOX)
    assert margin == pytest.approx(math.sqrt(10 * 1 / (25 * 50)))
    worst = np.array([50.0, 50.0, 1.0, 1.0])
    assert np.all(nuno_slack(params, worst, 0.999 * margin, 0.999 * margin) > 0)
    assert np.all(nuno_slack(params, worst, 1.001 * margin, 1.001 * margin) < 0)
    assert nuno_delay_margin(params, GainBox.uniform((0, 0), (1, 2))) == math.inf


def test_empty_polytope_and_round_trip():
    params = paper_setup()
    tight = nuno_polytope(params, GainBox.uniform((40, 50), (1, 2)), 1.0, 1.0)
    assert tight.is_empty()
    polytope = nuno_polytope(params, BOX, 0.5, 0.5)
    again = GainPolytope.from_dict(polytope.to_dict())
    np.testing.assert_array_equal(again.G, polytope.G)
    assert again.labels == polytope.labels
    with pytest.raises(ValueError, match="malformed"):
        GainPolytope.from_dict({"G": [[1.0]]})


@pytest.mark.parametrize("bounds", [(0.0, 1.0), (1.0, -1.0), (math.nan, 1.0), (1.0, math.inf)])
def test_bad_delay_bounds(bounds):
    with pytest.raises(ValueError, match="delay bound"):
        nuno_polytope(paper_setup(), BOX, *bounds)


def test_certificate_json_round_trip_and_malformed():
    from teleopkit.certification import certify_gains

    cert = certify_gains(paper_setup(), BOX, 0.05, 0.05, method="nuno")
    assert cert.certified
    again = load_certificate(cert.to_json())
    assert again.to_dict() == cert.to_dict()
    with pytest.raises(ValueError, match="malformed gain certificate"):
        load_certificate('{"certified": true}')
    with pytest.raises(ValueError, match="malformed gain certificate"):
        load_certificate("not json")
