"""Gain laws searched by CMA-ES: where they start, what they read, what they record."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from law_helpers import still_law

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import best_static_gains, static_cost
from teleopkit.rl.comparison import REFERENCE, compare
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import closed_loop
from teleopkit.rl.law_search import (
    LawSearchConfig,
    _Laws,
    _reference,
    _Seen,
    law_features,
    law_under,
    search_gain_law,
)
from teleopkit.rl.policy import GainPolicy
from teleopkit.safety.factory import layer_for
from teleopkit.setup import Setup

START = np.array([3.4, 7.4, 8.6, 18.5])  # about the paper's best constant gains
SHORT = FlexTeleopConfig(observation="adaptive", episode_length=4.0)
TANK = FlexTeleopConfig(certificate=default_certificate(variation="tank:3"),
                        observation="adaptive", episode_length=4.0)
SMALL = LawSearchConfig(generations=6, population=6, scenarios=8, validate_every=2,
                        validation_scenarios=8)


@pytest.fixture(scope="module")
def searched(tmp_path_factory):
    out = tmp_path_factory.mktemp("law")
    return search_gain_law(START, SMALL, SHORT, out_dir=out, progress=False), out


def test_a_law_reads_the_levels_the_delay_and_the_safety_layer_state():
    assert law_features(SHORT).tolist() == list(range(16, 23))  # 6 levels, the delay
    columns = layer_for(TANK.safety_certificate()).run_time_state(1).shape[1]
    assert columns > 0
    assert law_features(TANK).tolist() == list(range(16, 23 + columns))  # and the tank
    with pytest.raises(ValueError, match="adaptive"):
        law_features(FlexTeleopConfig())


def test_a_law_with_zero_weights_is_its_start_and_costs_what_the_start_gains_cost():
    low = np.ones(4)
    span = (START - low) / np.log(2.0)
    seen = _Seen(np.zeros(23), np.ones(23), np.full(23, -np.inf), np.full(23, np.inf))
    law = _Laws(np.zeros((1, 4 * 7 + 4)), law_features(SHORT), low, span, seen)
    obs = np.random.default_rng(0).normal(size=(5, 23))
    np.testing.assert_allclose(law(obs), np.tile(START, (5, 1)), rtol=1e-12)
    scenario = SHORT.setup.scenarios(np.random.default_rng(3), 4)
    run = closed_loop(law, scenario, SHORT)
    np.testing.assert_allclose(-run.reward.sum(axis=0), static_cost(START, scenario, SHORT)[0],
                               rtol=1e-9)


def test_the_search_beats_its_start_on_its_validation_scenarios(searched):
    result, _ = searched
    best = result.log["validation_objective"].min()
    assert best < 0.98 and (result.log["unsafe_actions"] == 0).all()
    chosen = result.log.loc[result.log["validation_objective"].idxmin()]
    assert result.policy.metadata["generation"] == chosen["generation"] > 0
    first = result.log.iloc[0]  # the start's own validation, the first candidate
    assert first["generation"] == 0 and first["validation_objective"] == 1.0
    assert first["validation_cost"] == first["start_cost"] == result.log["start_cost"].iloc[-1]
    # the policy file computes what the search validated
    validation = SHORT.setup.scenarios(np.random.default_rng(SMALL.validation_seed), 8)
    cost = -closed_loop(result.policy, validation, SHORT).reward.sum(axis=0)
    assert cost.mean() == pytest.approx(chosen["validation_cost"], rel=1e-9)


def test_a_law_file_records_what_it_was_searched_for(searched):
    result, out = searched
    loaded = GainPolicy.load(out / "best_policy.npz")
    assert loaded.fingerprint == result.policy.fingerprint and len(loaded.weights) == 1
    meta = loaded.metadata
    assert meta["setup"] == SHORT.setup.record and meta["observation"] == "adaptive"
    assert meta["law_search"]["population"] == SMALL.population
    assert meta["start"] == START.tolist() and meta["gain_variation"] == "frozen"
    pd.testing.assert_frame_equal(pd.read_csv(out / "search_log.csv"), result.log,
                                  check_dtype=False)


def test_a_law_never_extrapolates_beyond_the_observations_it_was_searched_on(searched):
    law = searched[0].policy
    lowest, highest = law.obs_range
    assert np.all(lowest < highest)  # every column moved during the standardisation run
    inside = np.random.default_rng(1).uniform(lowest, highest, size=(6, lowest.size))
    beyond = inside.copy()
    beyond[:, -1] = highest[-1] + 5.0  # a delay far longer than any the setup draws
    edge = inside.copy()
    edge[:, -1] = highest[-1]
    np.testing.assert_array_equal(law(beyond), law(edge))
    assert not np.allclose(law(inside), law(edge))  # the delay matters inside the range


def test_the_same_seed_gives_the_same_law():
    settings = LawSearchConfig(generations=2, population=3, scenarios=2, validate_every=1,
                               validation_scenarios=2)
    config = FlexTeleopConfig(observation="adaptive", episode_length=1.0)
    first = search_gain_law(START, settings, config, progress=False)
    again = search_gain_law(START, settings, config, progress=False)
    assert first.policy.fingerprint == again.policy.fingerprint


def test_a_search_that_finds_no_better_law_keeps_its_start():
    """Wide steps from the start: the one law of one generation costs more on validation."""
    settings = LawSearchConfig(generations=1, population=2, scenarios=2, sigma=2.0,
                               validation_scenarios=4)
    result = search_gain_law(START, settings, SHORT, progress=False)
    assert result.log["generation"].tolist() == [0, 1]
    assert result.log.loc[1, "validation_objective"] > 1.0  # the law found does worse
    assert result.policy.metadata["generation"] == 0
    obs = np.random.default_rng(2).normal(size=(5, 23))
    np.testing.assert_allclose(result.policy(obs), np.tile(START, (5, 1)), rtol=1e-12)
    validation = SHORT.setup.scenarios(np.random.default_rng(settings.validation_seed), 4)
    cost = -closed_loop(result.policy, validation, SHORT).reward.sum(axis=0)
    assert cost.mean() == pytest.approx(result.log.loc[0, "start_cost"], rel=1e-9)


@pytest.mark.parametrize(("settings", "message"), [
    ({"population": 1}, "population"), ({"sigma": 0.0}, "sigma"), ({"harm": -1.0}, "harm"),
    ({"harm": float("inf")}, "harm must be finite"), ({"harm": float("nan")}, "harm"),
    ({"generations": 0}, "generations"), ({"sigma": float("nan")}, "sigma"),
    ({"references": ((1.0, float("nan"), 3.0, 3.0),)}, "references"),
    ({"references": ((1.0, -1.0, 3.0, 3.0),)}, "references")])
def test_bad_settings_are_refused(settings, message):
    with pytest.raises(ValueError, match=message):
        LawSearchConfig(**settings)


def test_the_reference_of_a_scenario_is_the_cheapest_constant_gains_on_it():
    """Each scenario's reference: the cheapest of the start gains and the references, each
    reference's cost recomputed on its own by the environment's rollout."""
    scenario = SHORT.setup.scenarios(np.random.default_rng(5), 3)
    references = np.array([[1.3, 1.3, 3.3, 3.3], [8.0, 8.0, 22.0, 22.0]])
    start = -closed_loop(lambda obs: np.tile(START, (len(obs), 1)), scenario,
                         SHORT).reward.sum(axis=0)
    each = [-closed_loop(lambda obs, g=g: np.tile(g, (len(obs), 1)), scenario,
                         SHORT).reward.sum(axis=0) for g in references]
    reference, unsafe = _reference(start, references, scenario, SHORT)
    np.testing.assert_allclose(reference, np.min([start, *each], axis=0), rtol=1e-9)
    assert unsafe == 0 and np.any(reference < start)  # the soft gains beat the start somewhere
    assert _reference(start, np.empty((0, 4)), scenario, SHORT)[0] is start


def test_a_search_against_references_records_them():
    references = ((1.3, 1.3, 3.3, 3.3),)
    settings = LawSearchConfig(generations=1, population=2, scenarios=2, validate_every=1,
                               validation_scenarios=2, references=references)
    result = search_gain_law(START, settings, SHORT, progress=False)
    assert result.policy.metadata["law_search"]["references"] == references
    with pytest.raises(ValueError, match="references need 4 gains each"):
        search_gain_law(START, replace(settings, references=((1.0, 2.0),)), SHORT,
                        progress=False)


def test_a_start_on_the_box_floor_is_refused():
    with pytest.raises(ValueError, match="above the box's lower corner"):
        search_gain_law(np.array([1.0, 7.4, 8.6, 18.5]), SMALL, SHORT, progress=False)


SHORTER = Setup.paper().with_delay("constant:0.3")
NEAR = FlexTeleopConfig(SHORTER, default_certificate(SHORTER.params, (0.3, 0.3)),
                        observation="adaptive", episode_length=4.0)


@pytest.fixture(scope="module")
def moved():
    """A still law at the best constant gains of the 1 s set for 0.3 s delays, moved to 0.3 s."""
    searched_under = SHORT.safety_certificate()
    start = best_static_gains(layer_for(searched_under), config=NEAR, progress=False).gains
    law = still_law(start, searched_under)
    return law, law_under(law, NEAR, progress=False)


def test_a_law_under_the_set_it_was_searched_in_is_left_as_it_is(searched):
    law = searched[0].policy
    assert law_under(law, SHORT) is law
    same_set = replace(SHORT, episode_length=2.0)  # another question, the same certificate
    assert law_under(law, same_set) is law
    tuner = GainPolicy(law.weights, law.obs_mean, law.obs_std, law.low, law.span,
                       {"certificate": SHORT.safety_certificate().to_dict()})
    assert law_under(tuner, NEAR) is tuner  # not a law: nothing to move


def test_a_law_moved_onto_a_wider_set_starts_at_its_best_constant_gains(moved):
    law, there = moved
    after = best_static_gains(config=NEAR, progress=False).gains
    before = law.metadata["start"]
    assert after[0] > 2 * before[0]  # the 0.3 s set lets the stiffness double
    obs = np.random.default_rng(2).normal(size=(3, 23))
    np.testing.assert_allclose(there(obs), np.tile(after, (3, 1)), rtol=1e-9)
    assert there.metadata["start"] == pytest.approx(after.tolist(), rel=1e-9)
    assert there.metadata["certificate"] == NEAR.safety_certificate().to_dict()
    assert there.metadata["moved"]["best_static"] == pytest.approx(before, rel=1e-12)
    assert law_under(there, NEAR) is there  # moved once, for good


def test_a_comparison_runs_a_law_moved_onto_its_certificate(moved):
    law, _ = moved
    table = compare([law], 3, certificate=NEAR.safety_certificate(), setup=SHORTER,
                    duration=4.0, progress=False)
    cost = table.groupby("controller")["cost"].mean()
    # the still law moved onto the 0.3 s set plays that set's best constant gains
    assert cost["gain law (frozen)"] == pytest.approx(cost[REFERENCE], rel=1e-9)
    assert (table["unsafe_actions"] == 0).all()
