"""Falsification: adversarial nonlinear runs inside certified sets never diverge."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.nuno.condition import nuno_polytope
from teleopkit.model.params import paper_setup
from teleopkit.robustness.falsification import falsify, sample_polytope

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))


def test_samples_lie_inside_the_polytope(rng):
    polytope = nuno_polytope(paper_setup(), BOX, 1.0, 1.0)
    for vertices_only in (False, True):
        samples = sample_polytope(polytope, rng, 500, vertices_only)
        assert np.all(polytope.contains(samples, tol=1e-9))


@pytest.mark.parametrize("delays", ["switching", "bound"])
@pytest.mark.parametrize("switching", [False, True])
def test_no_divergence_inside_the_closed_form_set(delays, switching):
    params = paper_setup()
    polytope = nuno_polytope(params, BOX, 1.0, 1.0)
    report = falsify(params, polytope, 1.0, 1.0, batch=32, duration=30.0, switching=switching,
                     delays=delays, seed=3)
    assert len(report) == 32
    assert report["diverged"].sum() == 0, report.sort_values("growth").tail()


def test_the_falsifier_finds_an_unstable_gain():
    """A gain the exact spectrum calls unstable at 1 s (K_r = 50, B_r = 1) is caught."""
    params = paper_setup()
    outside = GainPolytope.from_box(GainBox.uniform((50.0, 50.0), (1.0, 1.0)))
    report = falsify(params, outside, 1.0, 1.0, batch=8, duration=40.0, switching=False,
                     delays="bound", seed=1)
    assert report["diverged"].all()
