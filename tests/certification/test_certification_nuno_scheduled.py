"""Tests of teleopkit.certification.nuno.scheduled: certificates of the scheduled gain classes."""

from __future__ import annotations

import math

import pytest
from scheduled_helpers import BOX, certified

from teleopkit.certification import GainBox, certify_gains, check_certificate, load_certificate
from teleopkit.model.params import paper_setup
from teleopkit.safety.factory import layer_for


@pytest.mark.parametrize("variation", ["scheduled:1", "tank", "tank:0.25"])
def test_certificate_round_trip_and_verify(variation):
    certificate = certified(variation)
    loaded = load_certificate(certificate.to_json())
    check_certificate(loaded)
    assert loaded.gain_variation == variation and loaded.certified is False
    assert loaded.polytope_certified and loaded.details["storage"]["cone"] == [2.5, 2.5]
    layer = layer_for(loaded)
    columns = 3 if variation.startswith("tank") else 2
    assert layer.run_time_state(2).shape == (2, columns)


def test_a_tampered_scheduled_certificate_is_refused():
    data = certified("scheduled:1").to_dict()
    data["details"]["storage"]["cone"] = [0.5, 0.5]
    import json

    with pytest.raises(ValueError, match="details"):
        load_certificate(json.dumps(data))


def test_the_certificate_says_what_it_covers():
    certificate = certify_gains(paper_setup(), GainBox.uniform((1.0, 20.0), (60.0, 150.0)),
                                1.0, 1.0, "nuno", "scheduled:1.5")
    assert certificate.certified
    text = " ".join(certificate.assumptions)
    assert "exp(1.5) V(0)" in text and "no torque saturation" in text
    assert "held between control samples" in text
    frozen = certify_gains(paper_setup(), BOX, 1.0, 1.0)
    assert any("without a published proof" in a for a in frozen.assumptions)
    one = certify_gains(paper_setup(), GainBox.uniform((10.0, 10.0), (30.0, 60.0)), 1.0, 1.0)
    assert not any("without a published proof" in a for a in one.assumptions)


@pytest.mark.parametrize("variation", ["scheduled:0.5", "tank"])
def test_falsification_inside_the_class_respects_the_storage_bound(variation):
    from teleopkit.robustness.adversary import SearchSpace
    from teleopkit.robustness.search import search

    space = SearchSpace(paper_setup(), certified(variation, paper_setup()), duration=6.0,
                        segments=12)
    assert space.params.torque_limit == math.inf and space.covered
    result = search(space, "storage", "random", budget=16, population=8, seed=1)
    assert result.storage_ratio <= result.storage_bound * (1 + 1e-6)
    assert not result.finding and not result.diverged
    assert "storage ratio" in result.summary()
