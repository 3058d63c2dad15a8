"""Training and evaluation follow the setup: comparators searched for it, policies record it."""

from __future__ import annotations

import numpy as np

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl import comparison
from teleopkit.rl.comparison import Comparators, comparators_for, evaluation_config
from teleopkit.setup import Setup

STILL = Setup.from_data({"plant": {"local_arm": {"lengths": [0.38, 0.38],
                                                 "masses": [0.5, 0.35]}},
                         "operator": {"motion": "still"}, "start": "rest"})


def test_comparators_are_searched_for_the_setup_given_and_cached_by_its_fingerprint(
        policy, monkeypatch):
    searched = []

    def find_static(cls, certificate, config):
        searched.append(config.setup)
        static = np.array([1.0, 2.0, 3.0, 4.0]) * len(searched)
        return cls("frozen", cls.key(certificate, config), static, static, None, None)

    monkeypatch.setattr(Comparators, "find_static", classmethod(find_static))
    policy.metadata.pop("comparators", None)
    certificate = default_certificate()
    paper = comparators_for(policy, certificate, evaluation_config(certificate))
    still = comparators_for(policy, certificate, evaluation_config(certificate, STILL))
    assert searched == [Setup.paper(), STILL]
    assert paper.fingerprint != still.fingerprint
    assert not np.array_equal(paper.frozen_static, still.frozen_static)
    again = comparators_for(policy, certificate, evaluation_config(certificate, STILL))
    assert len(searched) == 2 and np.array_equal(again.frozen_static, still.frozen_static)
    delayed = comparators_for(policy, certificate,
                              evaluation_config(certificate, STILL, "constant:0.4"))
    assert len(searched) == 3 and searched[-1].network.bounds == (0.4, 0.4)
    assert delayed.fingerprint != still.fingerprint


def test_the_frozen_reference_is_certified_on_the_tuners_box():
    from teleopkit.certification.certifier import certify_gains
    from teleopkit.certification.gain_sets import GainBox

    box = GainBox.uniform((2.0, 8.0), (20.0, 60.0))
    tank = certify_gains(STILL.params, box, 0.6, 0.6, method="nuno", variation="tank")
    frozen = comparison.frozen_counterpart(tank, STILL.params)
    assert frozen.gain_variation == "frozen" and frozen.box == box
    assert frozen.delay_bounds == (0.6, 0.6)


def test_a_policy_records_the_setup_it_was_trained_on():
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.training import TrainConfig, _Run

    run = _Run(TrainConfig(num_envs=2), FlexTeleopConfig(STILL))
    record = run.policy().metadata["setup"]
    assert record == STILL.record and record["operator"]["motion"] == "still"
    assert run.fingerprint()["setup"] == STILL.fingerprint
