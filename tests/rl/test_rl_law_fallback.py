"""A gain law steps aside for the best constant gains of a setup where they are cheaper."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from law_helpers import still_law

from teleopkit.cli import main
from teleopkit.rl.baselines import BASELINE_SEED, static_cost
from teleopkit.rl.comparison import REFERENCE, as_run, compare
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED
from teleopkit.rl.law_search import DECISION_SEED, law_or_static, stepped_aside
from teleopkit.setup import Setup

SHORT = FlexTeleopConfig(observation="adaptive", episode_length=4.0)
GOOD = np.array([3.4, 7.4, 8.6, 18.5])  # about the paper's best constant gains
STIFF = np.array([30.0, 30.0, 100.0, 100.0])  # dear on the gain term, and no better tracking


@pytest.fixture(scope="module")
def stiff_law():
    return still_law(STIFF, SHORT.safety_certificate())


def test_a_law_dearer_than_the_constant_gains_plays_them_and_says_why(stiff_law):
    aside = law_or_static(stiff_law, SHORT, GOOD, scenarios=4)
    obs = np.random.default_rng(1).normal(size=(5, stiff_law.obs_mean.size)) * 100
    np.testing.assert_array_equal(aside(obs), np.tile(GOOD, (5, 1)))
    record = aside.metadata["stepped_aside"]
    drawn = SHORT.setup.scenarios(DECISION_SEED, 4)
    assert record["static_cost"] == pytest.approx(static_cost(GOOD, drawn, SHORT)[0].mean(),
                                                  rel=1e-9)
    assert record["law_cost"] > record["static_cost"]
    assert record["static"] == GOOD.tolist() and record["setup"] == SHORT.setup.fingerprint
    # decided on scenarios neither the constant gains were fitted to nor an evaluation uses
    assert record["seed"] == DECISION_SEED and DECISION_SEED not in (BASELINE_SEED, EVAL_SEED)
    assert all(np.array_equal(a, b) for pair, other in zip(aside.weights, stiff_law.weights,
                                                           strict=True)
               for a, b in zip(pair, other, strict=True))  # which law stepped aside
    assert law_or_static(aside, SHORT, STIFF, scenarios=4) is aside  # decided once
    said = stepped_aside(aside)
    assert said.startswith("steps aside on this setup: on 4 fresh scenarios of it, it cost")
    assert "(3.4, 7.4, 8.6, 18.5)" in said and stepped_aside(stiff_law) is None


def test_a_law_no_dearer_than_the_constant_gains_runs_as_it_is():
    law = still_law(GOOD, SHORT.safety_certificate())
    assert law_or_static(law, SHORT, STIFF, scenarios=4) is law
    assert law_or_static(law, SHORT, GOOD, scenarios=4) is law  # a tie keeps the law


def test_a_policy_that_is_not_a_law_runs_as_it_is(stiff_law):
    tuner = type(stiff_law)(stiff_law.weights, stiff_law.obs_mean, stiff_law.obs_std,
                            stiff_law.low, stiff_law.span, {})
    assert law_or_static(tuner, SHORT, GOOD, scenarios=4) is tuner


@pytest.fixture(scope="module")
def compared(stiff_law):
    return compare([stiff_law], 3, duration=4.0, progress=False)


def test_a_law_that_stepped_aside_costs_what_its_class_constant_gains_cost(compared):
    cost = compared.pivot_table(index="scenario", columns="controller", values="cost")
    np.testing.assert_allclose(cost["gain law (frozen)"], cost[REFERENCE], rtol=1e-12)
    assert cost["gain law (frozen)"].mean() < cost["fixed"].mean()
    assert (compared["unsafe_actions"] == 0).all()


def test_the_comparators_schedule_is_the_law_as_it_runs(stiff_law):
    config = FlexTeleopConfig(episode_length=4.0)
    certificate = config.safety_certificate()
    assert as_run([stiff_law], certificate, config, fall_back=False)[0][0] is stiff_law
    (running,), comparators = as_run([stiff_law], certificate, config)  # by default
    assert "stepped_aside" in running.metadata
    np.testing.assert_allclose(running(np.zeros((1, stiff_law.obs_mean.size)))[0],
                               comparators.class_static, rtol=1e-12)


def test_evaluate_says_when_a_law_steps_aside(stiff_law, tmp_path, capsys):
    path = tmp_path / "stiff.npz"
    stiff_law.save(path)
    assert main(["evaluate", "--policy", str(path), "--scenarios", "2", "--duration", "2",
                 "--out", str(tmp_path / "eval")]) == 0
    err = capsys.readouterr().err
    assert "stiff.npz steps aside on this setup: on 32 fresh scenarios of it, it cost" in err
    assert "stiff.npz steps aside on this setup" in (tmp_path / "eval" / "summary.md").read_text()
    summary = pd.read_csv(tmp_path / "eval" / "summary.csv", index_col=0)
    assert summary.loc["gain law (frozen)", "cost"] == pytest.approx(
        summary.loc[REFERENCE, "cost"], rel=1e-9)
    assert main(["evaluate", "--policy", str(path), "--scenarios", "2", "--duration", "2",
                 "--no-fall-back", "--out", str(tmp_path / "searched")]) == 0
    assert "steps aside" not in capsys.readouterr().err
    searched = pd.read_csv(tmp_path / "searched" / "summary.csv", index_col=0)
    assert searched.loc["gain law (frozen)", "cost"] > summary.loc[REFERENCE, "cost"]


def test_the_shipped_law_runs_as_it_is_on_the_paper_setup():
    """It beats the paper's best constant gains of its class on fresh scenarios of the setup."""
    from teleopkit.rl.comparison import evaluation_config, policy_certificate
    from teleopkit.rl.policy import GainPolicy

    law = GainPolicy.load("law")
    certificate = policy_certificate(law)
    config = evaluation_config(certificate, Setup.paper())
    static = np.array([4.139, 4.139, 10.347, 18.295])  # its class's best there
    assert law_or_static(law, config, static) is law
