"""Tests of teleopkit.rl.evaluation: baselines, held-out evaluation and reports."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from teleopkit.rl.baselines import FIXED_GAINS, best_static_gains, fixed_gains, static_cost
from teleopkit.rl.comparison import policy_certificate
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import (
    SUMMARY_METRICS,
    closed_loop,
    cost_ratio,
    episode_costs,
    evaluate,
    findings,
    rollout,
    save_report,
    summarise,
)
from teleopkit.rl.policy import PRETRAINED_COVERED, GainPolicy
from teleopkit.sim.scenarios import paper_scenarios

torch.set_num_threads(1)

SHORT = FlexTeleopConfig(episode_length=0.3)
ONE_SECOND = FlexTeleopConfig(episode_length=1.0)  # the delayed operator motion arrives at 0.45 s


def wild(obs):
    """Gains far outside the set, with NaN and inf."""
    rng = np.random.default_rng(len(obs) + int(abs(obs).sum() * 1e6) % 1000)
    action = rng.uniform(-100, 400, (len(obs), 4))
    action[rng.random(action.shape) < 0.1] = np.nan
    action[:, 0][rng.random(len(obs)) < 0.1] = np.inf
    return action


def test_static_cost_is_the_environment_return(layer):
    gains = layer.project_batch(np.array([[10.0, 10, 30, 30], [40.0, 3, 60, 150]])).action
    costs = static_cost(gains, paper_scenarios(11, 3), ONE_SECOND)
    assert np.ptp(costs) > 1
    for gain, cost in zip(gains, costs, strict=True):
        run = rollout(ConstantGains(gain), 3, 11, ONE_SECOND)
        np.testing.assert_allclose(-run.reward.sum(axis=0), cost, rtol=1e-12)


def test_episode_costs_are_the_closed_loop_costs_and_refuse_a_failed_run(policy):
    scenario = paper_scenarios(12, 3)
    costs, unsafe = episode_costs(policy, scenario, ONE_SECOND)
    np.testing.assert_array_equal(costs, -closed_loop(policy, scenario, ONE_SECOND).reward.sum(
        axis=0))
    assert unsafe == 0 and np.ptp(costs) > 0
    with pytest.raises(RuntimeError, match="left the state bound"):
        episode_costs(wild, scenario, FlexTeleopConfig(episode_length=0.3, state_bound=0.05))


def test_every_applied_action_lies_in_the_set(layer, policy):
    for controller in (policy, wild, ConstantGains(np.array([60.0, 0.0, 1.0, 200.0]))):
        run = rollout(controller, 4, 3, SHORT)
        assert run.unsafe_actions == 0
        assert layer.polytope.contains(run.applied).all()
    assert np.any(np.linalg.norm(run.raw - run.applied, axis=-1) > 1)  # the layer did work


def test_evaluate_and_summarise(policy, tmp_path):
    per = evaluate({"TD3": [policy, policy], "fixed": ConstantGains(fixed_gains())},
                   scenarios=3, seed=5, config=SHORT)
    assert len(per) == 9 and set(per["controller"]) == {"TD3", "fixed"}
    summary = save_report(per, tmp_path, baseline="fixed")
    assert list(summary.index) == ["TD3", "fixed"]
    td3 = per[per["controller"] == "TD3"]
    assert summary.loc["TD3", "cost"] == pytest.approx(td3["cost"].mean())
    assert summary.loc["TD3", "cost_std"] == pytest.approx(td3["cost"].std())
    assert summary.loc["TD3", "cost_seed_std"] == pytest.approx(0.0)  # the same policy twice
    assert np.isnan(summary.loc["fixed", "cost_seed_std"])
    assert summary.loc["TD3", "policies"] == 2 and summary["unsafe_actions"].sum() == 0
    assert (per["rms_track"] > 0).all() and (per["iae_damp"] > 0).all()
    table = (tmp_path / "summary.md").read_text()
    assert table.startswith("| controller | certificate | covered | cost |") and "+0.0 %" in table
    saved = pd.read_csv(tmp_path / "summary.csv")
    assert {"controller", "certificate", "covered", "cost", "rms_track", "rms_damp"} <= set(saved)
    # a switching policy is not covered by the frozen default; constant gains are
    assert summary.loc["fixed", "covered"] and summary.loc["fixed", "certificate"] == "frozen"
    assert not summary.loc["TD3", "covered"] and (td3["gain_changes"] > 0).all()
    assert pd.read_csv(tmp_path / "per_scenario.csv").shape == per.shape


def test_held_out_scenarios_depend_on_the_seed_only(policy):
    a = rollout(policy, 2, 8, ONE_SECOND).metrics()
    b = rollout(policy, 2, 8, ONE_SECOND).metrics()
    c = rollout(policy, 2, 9, ONE_SECOND).metrics()
    pd.testing.assert_frame_equal(a, b)
    assert not np.allclose(a["cost"], c["cost"])


def test_unseen_delay_shapes_keep_the_scenarios_and_change_the_delays(policy):
    paper = rollout(policy, 2, 8, ONE_SECOND)
    switching = rollout(policy, 2, 8, ONE_SECOND, delay="switching:0:1:50ms")
    assert np.array_equal(paper.trajectory.state[0], switching.trajectory.state[0])
    delays = switching.trajectory.delays[:, :, 0]
    assert set(np.round(delays, 9).ravel()) == {0.0, 1.0}
    assert not np.allclose(paper.metrics()["cost"], switching.metrics()["cost"])
    assert switching.unsafe_actions == 0
    with pytest.raises(ValueError, match="unknown delay spec"):
        evaluate({"TD3": policy}, 2, config=ONE_SECOND, delay="warp:3")


def test_best_static_gains_are_certified_and_beat_the_grid_and_the_paper(layer):
    config = FlexTeleopConfig(episode_length=1.0)
    found = best_static_gains(layer, scenarios=3, seed=1, grid_points=4, max_evaluations=40,
                              config=config)
    assert layer.polytope.contains(found.gains)
    assert found.cost <= found.grid_cost
    scenario = paper_scenarios(1, 3)
    assert found.cost == pytest.approx(static_cost(found.gains, scenario, config).mean())
    assert found.cost < static_cost(fixed_gains(*FIXED_GAINS), scenario, config).mean()
    assert found.evaluations <= 16 + 41


def test_rollout_frame_has_the_figure_columns(policy, tmp_path):
    from teleopkit.plots import save_paper_figures

    frame = rollout(policy, 1, 0, SHORT).to_frame()
    assert len(frame) == 31 and frame["Tl"].notna().all()
    paths = save_paper_figures({"TD3": frame, "fixed": frame}, tmp_path)
    assert [p.name for p in paths] == ["delay_profile.png", "adaptive_gains.png", "positions.png",
                                       "tracking_error.png", "damping_error.png"]
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in paths)


def test_shipped_policy_loads_and_is_small():
    policy = GainPolicy.pretrained()
    assert policy.action_dim == 4 and len(policy.metadata["best_static_gains"]) == 4
    from importlib import resources

    with resources.as_file(resources.files("teleopkit") / "data" / "td3_policy.npz") as path:
        assert path.stat().st_size < 300_000


def test_shipped_covered_policy_runs_covered_in_its_class():
    policy = GainPolicy.pretrained(PRETRAINED_COVERED)
    certificate = policy_certificate(policy)
    variation = certificate.gain_variation
    config = FlexTeleopConfig(certificate=certificate, episode_length=1.0)
    static = np.asarray(policy.metadata["comparators"]["class_static"])
    assert certificate.polytope.contains(static[None], tol=1e-9).all()
    run = rollout(policy, 2, 8, config)
    table = run.metrics()
    assert run.unsafe_actions == 0 and table["covered"].all()
    assert (table["certificate"] == variation).all()


def _table(costs: dict[str, tuple[list[float], bool]]) -> pd.DataFrame:
    """A per-scenario table of given costs (one policy each) and coverage."""
    return pd.DataFrame([{"controller": name, "policy": 0, "scenario": k,
                          **dict.fromkeys(SUMMARY_METRICS, cost), "covered": covered,
                          "certificate": "tank:3", "unsafe_actions": 0}
                         for name, (values, covered) in costs.items()
                         for k, cost in enumerate(values)])


def test_findings_compare_the_tuner_with_the_strongest_covered_row():
    rng = np.random.default_rng(3)
    base = rng.uniform(8000, 12000, 32)
    per = _table({"TD3": (list(base - 500 + rng.normal(0, 50, 32)), True),
                  "best static": (list(base), True),
                  "open-loop": (list(base - 480 + rng.normal(0, 50, 32)), True),
                  "paper": (list(base - 2000), False)})
    text = findings(summarise(per), per, "TD3", "best static")
    assert "`TD3` costs least" in text or "`open-loop` costs least" in text
    assert "strongest other covered row, `open-loop`" in text
    assert "no measurable difference" in text  # 20 apart, with 50 of noise per scenario
    assert "not covered by their certificate: `paper`" in text
    per = _table({"TD3": (list(base - 500), True), "best static": (list(base), True)})
    text = findings(summarise(per), per, "TD3", "best static")
    assert "`TD3` costs least (-" in text and "`best static`: -" in text and "cheaper" in text


def test_cost_ratio_weighs_every_scenario_the_same():
    per = _table({"law": ([1.0, 100.0, 30.0], True), "schedule": ([2.0, 100.0, 20.0], True)})
    mean, error = cost_ratio(per, "law", "schedule")
    ratios = np.array([0.5, 1.0, 1.5])
    assert mean == pytest.approx(ratios.mean() - 1)  # 0, while the mean costs differ by +7 %
    assert error == pytest.approx(ratios.std(ddof=1) / np.sqrt(3))


def test_findings_set_the_tuner_against_its_own_schedule():
    rng = np.random.default_rng(5)
    base = rng.uniform(8000, 12000, 32)
    per = _table({"law": (list(0.9 * base), True), "best static": (list(0.8 * base), True),
                  "schedule": (list(base), True)})
    text = findings(summarise(per), per, "law", "best static", schedule="schedule")
    assert "strongest other covered row, `best static`: +12.5 % cost" in text
    assert "Against its own open-loop schedule, `schedule`" in text
    assert "scenario by scenario -10.0 ± 0.0 % on average), cheaper." in text
    assert "open-loop schedule" not in findings(summarise(per), per, "law", "best static")


def test_findings_say_when_the_tuner_is_not_covered(tmp_path):
    per = _table({"TD3": ([1.0, 2.0], False), "fixed": ([2.0, 3.0], True)})
    save_report(per, tmp_path, baseline="fixed", tuner="TD3")
    text = (tmp_path / "summary.md").read_text()
    assert "`fixed` costs least (+0.0 % against `fixed`)" in text
    assert "`TD3` is not covered by its certificate" in text
    assert "Cheaper but not covered" not in text  # only the tuner is cheaper, named above
