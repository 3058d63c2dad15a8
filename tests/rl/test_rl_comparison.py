"""A tuner's certificate travels with it; evaluation refuses one that does not cover it."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_classes import parse_gain_variation
from teleopkit.rl.comparison import (
    REFERENCE,
    Comparators,
    check_covers,
    compare,
    policy_certificate,
    tuner_rows,
)
from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.td3 import TD3

torch.set_num_threads(1)

TANK = default_certificate(variation="tank:3")


def tank_policy():
    env = FlexTeleopVectorEnv(1, FlexTeleopConfig(certificate=TANK, episode_length=0.2))
    return TD3.for_env(env, seed=0).policy({"certificate": TANK.to_dict(),
                                            "gain_variation": TANK.gain_variation})


@pytest.mark.parametrize(("wide", "narrow", "covers"), [
    ("switching", "frozen", True), ("switching", "rate:5", True), ("rate:5", "rate:2", True),
    ("rate:2", "rate:5", False), ("frozen", "switching", False), ("tank:3", "tank:1", True),
    ("tank:1", "tank:3", False), ("scheduled:2", "scheduled:0", True),
    ("scheduled:2", "tank:1", False), ("tank:3", "frozen", False), ("frozen", "frozen", True),
    ("tank:1rad", "tank:1", False),
])
def test_which_class_covers_which(wide, narrow, covers):
    assert parse_gain_variation(wide).covers(parse_gain_variation(narrow)) is covers


def test_a_policy_names_its_certificate_and_refuses_a_narrower_one():
    policy = tank_policy()
    assert policy_certificate(policy).gain_variation == "tank:3"
    check_covers(TANK, policy)
    with pytest.raises(ValueError, match="does not cover the policy's class tank:3"):
        check_covers(default_certificate(variation="tank:1"), policy)
    with pytest.raises(ValueError, match="does not cover"):
        check_covers(default_certificate(), policy)


def test_an_edited_recorded_certificate_is_refused():
    policy = tank_policy()
    data = json.loads(json.dumps(policy.metadata["certificate"]))
    data["details"]["set"]["cone"] = [0.5, 0.5]
    policy.metadata["certificate"] = data
    with pytest.raises(ValueError, match="details"):
        policy_certificate(policy)


def test_the_comparison_always_has_the_frozen_reference():
    policy = tank_policy()
    short = np.array([[2.0, 2.0, 5.0, 5.0]] * 20)
    comparators = Comparators("tank:3", Comparators.key(TANK, FlexTeleopConfig(certificate=TANK)),
                              np.array([3.4, 7.4, 8.6, 18.5]), np.array([3.0, 3.0, 7.5, 7.5]),
                              (3.0, 1.0, 40.0), short)
    table = compare([policy], 2, 5, duration=0.2, comparators=comparators)
    names = list(dict.fromkeys(table["controller"]))
    assert names == ["TD3 (tank:3)", REFERENCE, "best static (tank:3)", "semi-active (tank:3)",
                     "open-loop (tank:3)", "fixed"]
    rows = table.drop_duplicates("controller").set_index("controller")
    assert rows.loc[REFERENCE, "certificate"] == "frozen"
    assert rows.loc["semi-active (tank:3)", "certificate"] == "tank:3"
    assert table["covered"].all() and (table["unsafe_actions"] == 0).all()
    again = Comparators.from_dict(json.loads(json.dumps(comparators.to_dict())))
    key = again.key(TANK, FlexTeleopConfig(certificate=TANK))
    assert key == again.fingerprint and again.semi_active == (3.0, 1.0, 40.0)


def test_a_tuner_plays_with_what_it_observes_and_how_often_it_decides():
    """A policy trained on the adaptive observation, deciding every 5 periods, is compared so."""
    config = FlexTeleopConfig(certificate=TANK, episode_length=0.2, observation="adaptive",
                              decision_period=5)
    policy = TD3.for_env(FlexTeleopVectorEnv(1, config), seed=0).policy(
        {"certificate": TANK.to_dict(), "gain_variation": TANK.gain_variation,
         "observation": "adaptive", "decision_period": 5})
    short = np.array([[2.0, 2.0, 5.0, 5.0]] * 20)
    comparators = Comparators("tank:3", "any", np.array([3.4, 7.4, 8.6, 18.5]),
                              np.array([3.0, 3.0, 7.5, 7.5]), (3.0, 1.0, 40.0), short)
    table = compare([policy], 2, 5, duration=0.2, comparators=comparators)
    tuner = table[table["controller"] == "TD3 (tank:3)"]
    assert len(tuner) == 2 and (tuner["unsafe_actions"] == 0).all()
    # held over 5 periods: at most 4 distinct gains in the 20 periods of each run
    schedule = Comparators("tank:3", "any", short[0], short[0], (3.0, 1.0, 40.0), None)
    played = schedule.for_policy(policy, FlexTeleopConfig(certificate=TANK, episode_length=0.2))
    assert played.schedule.shape == (20, 4)
    assert len(np.unique(played.schedule.round(12), axis=0)) <= 4


def test_policies_share_a_row_only_when_they_are_one_kind_with_one_observation():
    from teleopkit.rl.policy import GainPolicy

    def made(observation: str, law: bool) -> GainPolicy:
        metadata = {"observation": observation, **({"law_search": {}} if law else {})}
        return GainPolicy([(np.zeros((4, 3)), np.zeros(4))], np.zeros(3), np.ones(3),
                          np.ones(4), np.ones(4), metadata)

    seeds = [made("paper", False), made("paper", False)]
    law, adaptive = made("adaptive", True), made("adaptive", False)
    assert tuner_rows(seeds, "tank:3") == {"TD3 (tank:3)": seeds}
    rows = tuner_rows([seeds[0], law, seeds[1], adaptive], "tank:3")
    assert rows == {"TD3 (tank:3, paper)": seeds, "gain law (tank:3)": [law],
                    "TD3 (tank:3, adaptive)": [adaptive]}


def test_the_report_names_a_searched_law_so_and_a_td3_tuner_trained():
    """A gain law is searched by CMA-ES, not trained: summary.md says which the tuner is."""
    from teleopkit.rl.comparison import report_preamble, tuner_label
    from teleopkit.rl.policy import GainPolicy

    def made(law: bool) -> GainPolicy:
        return GainPolicy([(np.zeros((4, 3)), np.zeros(4))], np.zeros(3), np.ones(3),
                          np.ones(4), np.ones(4), {"law_search": {}} if law else {})

    comparators = Comparators("tank:3", "any", np.array([3.4, 7.4, 8.6, 18.5]),
                              np.array([3.0, 3.0, 7.5, 7.5]), (3.0, 1.0, 40.0), None)

    def opening(policy: GainPolicy, policies: int) -> str:
        return report_preamble(comparators, 2, 5, "paper", tuner_label(policy, "tank:3"),
                               policies)

    law = opening(made(True), 1)
    assert "`gain law (tank:3)` is the gain law searched by CMA-ES (1 law);" in law
    assert "trained tuner" not in law
    assert "searched by CMA-ES (3 laws)" in opening(made(True), 3)
    assert "`TD3 (tank:3)` is the trained tuner (1 policy);" in opening(made(False), 1)
    assert "the trained tuner (2 policies)" in opening(made(False), 2)
