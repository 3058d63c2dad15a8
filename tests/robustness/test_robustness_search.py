"""Falsification search: decisions stay in the certified set; unstable sets are caught."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from teleopkit.certification import GainCertificate, certify_gains
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.model.params import paper_setup
from teleopkit.robustness.adversary import SearchSpace, decode, gain_schedule
from teleopkit.robustness.search import search
from teleopkit.safety.polytope import PolytopeLayer

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))


@pytest.fixture(scope="module")
def nuno() -> GainCertificate:
    return certify_gains(paper_setup(), BOX, 1.0, 1.0, "nuno")


@pytest.mark.parametrize("delays", ["square", "segments"])
@pytest.mark.parametrize("switching", [False, True])
def test_decisions_stay_inside_the_polytope_and_the_delay_bounds(nuno, rng, delays, switching):
    space = SearchSpace(paper_setup(), nuno, switching, delays, duration=2.0)
    decision = decode(space, rng.random((32, space.dimension)), PolytopeLayer(nuno.polytope))
    assert np.all(nuno.polytope.contains(decision.gains, tol=1e-7))
    t = np.linspace(0.0, 2.0, 401)
    for profile in (decision.forward, decision.backward):
        values = profile.sample(t)
        assert values.shape == (401, 32) and values.min() >= 0 and values.max() <= 1.0
    distinct = len(np.unique(decision.gains[0], axis=0))
    assert distinct == (1 if not switching else space.segments)
    assert space.covered == (not switching)


def test_a_rate_bound_limits_every_step_of_the_schedule(rng):
    cert = certify_gains(paper_setup(), GainBox.uniform((5.0, 10.0), (30.0, 60.0)), 1.0, 1.0,
                         "nuno")
    rated = replace(cert, gain_variation="rate:50")
    space = SearchSpace(paper_setup(), rated, duration=3.0)
    decision = decode(space, rng.random((4, space.dimension)), PolytopeLayer(cert.polytope))
    schedule = gain_schedule(space, decision)
    assert schedule.shape == (300, 4, 4)
    assert np.abs(np.diff(schedule, axis=0)).max() <= 50 * 0.01 + 1e-12
    assert np.all(cert.polytope.contains(schedule, tol=1e-7))


def test_search_reports_the_worst_case_with_its_trajectory(nuno):
    space = SearchSpace(paper_setup(), nuno, duration=12.0)
    result = search(space, "energy_growth", "random", budget=8, population=4, seed=1)
    assert result.evaluations == 8 and len(result.history) == 8
    assert result.value == pytest.approx(result.history["objective"].max())
    assert result.covered and not result.finding
    assert {"t", "Tl", "Tr", "Kr_1", "Br_2", "e_track_1"} <= set(result.trajectory.columns)
    assert result.trajectory["Tl"].between(0, 1).all()
    assert "nuno (frozen)" in result.summary()


def test_cma_search_catches_a_set_that_is_not_stable():
    """K_r = 50, B_r = 1 is unstable for a constant 1 s delay: the search must say DIVERGED."""
    box = GainBox.uniform((50.0, 50.0), (1.0, 1.0))
    base = certify_gains(paper_setup(), BOX, 1.0, 1.0, "nuno")
    unsafe = replace(base, certified=False, box=box, polytope=GainPolytope.from_box(box),
                     polytope_certified=False)
    space = SearchSpace(paper_setup(), unsafe, delays="segments", segments=2, duration=30.0)
    result = search(space, "energy_growth", "cma", budget=16, population=8, seed=0)
    assert result.diverged and not result.covered and not result.finding
    assert "DIVERGED" in result.summary() and "OUTSIDE" in result.summary()
