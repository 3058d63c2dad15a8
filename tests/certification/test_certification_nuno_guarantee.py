"""The storage bound in the plant's units, checked along adversarial runs of the shipped tuner."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from teleopkit.certification import certify_gains
from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.nuno.guarantee import start_storage
from teleopkit.certification.verification import check_certificate
from teleopkit.model.params import InitialState, paper_setup
from teleopkit.rl.comparison import policy_certificate
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.policy import PRETRAINED_COVERED, GainPolicy
from teleopkit.robustness.adversary import SearchSpace
from teleopkit.robustness.search import search


def test_the_start_storage_is_the_storage_of_a_run_at_its_first_sample():
    """V(0) of the bound, computed from the start, against the storage evaluated on a run."""
    certificate = default_certificate(variation="scheduled:0")
    gains = np.array([3.0, 3.0, 7.6, 7.6])
    run = rollout(ConstantGains(gains), 2, 5, FlexTeleopConfig(
        certificate=certificate, episode_length=0.1))
    value = certificate.storage.value(paper_setup(), run.trajectory)
    assert value[0] == pytest.approx(start_storage(paper_setup(), certificate.storage, 3.0),
                                     rel=1e-12)
    # the paper's start: operator spring 0.4 J / 25, 1 J of spring energy / kappa, mismatch 0.04
    assert start_storage(paper_setup(), certificate.storage, 1.0) == pytest.approx(1.056)


def test_bounds_follow_the_class():
    frozen_box = default_certificate(variation="scheduled:0").guarantee()
    tank = default_certificate(variation="tank:3").guarantee()
    assert tank.storage_bound == pytest.approx(frozen_box.storage_bound + 3.0)
    assert frozen_box.deflection[0] == pytest.approx(math.sqrt(2 * 50 * 1.056 / 100))
    assert frozen_box.motor_speed[0] == pytest.approx(math.sqrt(2 * 50 * 1.056 / 0.3))
    assert frozen_box.mismatch[0] == pytest.approx(math.sqrt(2 * 1.056))
    budget = default_certificate(variation="scheduled:0.5").guarantee()
    assert budget.storage_bound == pytest.approx(math.exp(0.5) * 1.056)
    assert default_certificate().guarantee() is None  # a frozen certificate has no storage


def test_a_tank_asked_for_as_a_deflection_allows_exactly_that_deflection():
    certificate = default_certificate(variation="tank:1.5rad")
    assert certificate.gain_variation.startswith("tank:1.19")
    # the level is recorded to six significant digits, rounded down: at most 1.5 rad
    assert 1.5 * (1 - 1e-5) <= certificate.guarantee().deflection[0] <= 1.5
    check_certificate(certificate)  # the recorded level reads back as the one of its set
    with pytest.raises(ValueError, match=r"the start alone allows 1\.028 rad"):
        default_certificate(variation="tank:0.5rad")


def test_a_narrow_stiffness_range_tightens_the_bound():
    narrow = certify_gains(paper_setup(), GainBox.uniform((4.139, 4.139), (1.0, 150.0)),
                           variation="scheduled:0")
    assert narrow.guarantee().deflection[0] == pytest.approx(0.157, abs=5e-4)
    moved = narrow.guarantee(InitialState((0.0, 0.0), (0.05, -0.05), (0.0, 0.0)))
    assert moved.storage_start < narrow.guarantee().storage_start


def test_adversarial_delays_keep_the_shipped_tuner_within_its_bounds():
    """CMA-ES over square-wave delays, the shipped covered tuner in closed loop (its class)."""
    tuner = GainPolicy.pretrained(PRETRAINED_COVERED)
    certificate = policy_certificate(tuner)
    space = SearchSpace(paper_setup(), certificate, duration=4.0, controller=tuner)
    assert space.covered and space.storage_bound == 1.0
    result = search(space, objective="storage", budget=32, population=16, seed=3)
    assert result.storage_ratio <= 1.0 + 1e-7
    guarantee = certificate.guarantee()
    run = result.trajectory
    for i in (1, 2):  # the worst run's motion within what the storage allows
        assert np.abs(run[f"qr_{i}"] - run[f"theta_{i}"]).max() <= guarantee.deflection[i - 1]
        assert np.abs(run[f"dtheta_{i}"]).max() <= guarantee.motor_speed[i - 1]
        assert np.abs(run[f"ql_{i}"] - run[f"theta_{i}"]).max() <= guarantee.mismatch[i - 1]


def test_the_storage_bound_holds_from_starts_training_never_saw():
    tuner = GainPolicy.pretrained(PRETRAINED_COVERED)
    certificate = policy_certificate(tuner)
    start = InitialState((0.3, -0.1), (0.1, 0.2), (-0.2, 0.0))
    params = replace(paper_setup(), initial=start)
    space = SearchSpace(params, certificate, duration=3.0, controller=tuner)
    result = search(space, objective="storage", method="random", budget=16, population=16)
    assert result.storage_ratio <= 1.0 + 1e-7
