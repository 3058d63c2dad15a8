"""Tests of teleopkit.certification.nuno.condition: the closed-form (Nuño) condition."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_certification_gain_sets import BOX

from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.nuno.condition import nuno_delay_margin, nuno_polytope, nuno_slack
from teleopkit.model.params import paper_setup


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


@pytest.mark.parametrize("bounds", [(0.0, 1.0), (1.0, -1.0), (math.nan, 1.0), (1.0, math.inf)])
def test_bad_delay_bounds(bounds):
    with pytest.raises(ValueError, match="delay bound"):
        nuno_polytope(paper_setup(), BOX, *bounds)
