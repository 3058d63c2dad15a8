"""Minimum delays: LMI certificates for delays in [T_min, T*], bound to the profiles they cover."""

from __future__ import annotations

import json

import numpy as np
import pytest

from certify import exact_constant_margin
from teleopkit.certification import GainCertificate, certify_gains, load_certificate
from teleopkit.certification.gain_classes import parse_gain_variation
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.systems import gain_set_system
from teleopkit.certification.lmi.verdict import lmi_assumptions
from teleopkit.cli import main
from teleopkit.delays.adversarial import PiecewiseDelay, SquareWaveDelay
from teleopkit.delays.combinators import scale_delay, stack_delays
from teleopkit.delays.profiles import (
    ConstantDelay,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
    delay_floor,
)
from teleopkit.sim.scenarios import PAPER_DELAY_FLOOR, paper_scenarios

NARROW = GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1)
FLOOR = 0.45


@pytest.fixture(scope="module")
def from_zero(one_joint) -> GainCertificate:
    return certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi")


@pytest.fixture(scope="module")
def with_floor(one_joint) -> GainCertificate:
    return certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi", tl_min=FLOOR, tr_min=FLOOR)


def test_a_minimum_delay_enlarges_the_margin_and_stays_below_the_exact_interval(
        one_joint, from_zero, with_floor):
    assert with_floor.certified and with_floor.delay_lower == (FLOOR, FLOOR)
    assert with_floor.delay_margin > from_zero.delay_margin
    system = gain_set_system(one_joint, GainPolytope.from_box(NARROW), "frozen")
    exact = min(exact_constant_margin(vertex, FLOOR) for vertex in system.vertices)
    assert with_floor.delay_margin <= exact
    assert any(f"T_l_min = {FLOOR:g} s" in text for text in with_floor.assumptions)


def test_the_closed_form_covers_delays_from_zero_whatever_the_floor(one_joint):
    cert = certify_gains(one_joint, NARROW, 1.0, 1.0, tl_min=FLOOR, tr_min=FLOOR)
    assert cert.delay_lower == (0.0, 0.0)
    assert cert.to_json() == certify_gains(one_joint, NARROW, 1.0, 1.0).to_json()


def test_an_interval_certificate_round_trips_and_refuses_edits(with_floor):
    again = load_certificate(with_floor.to_json())
    assert again.delay_lower == with_floor.delay_lower
    data = json.loads(with_floor.to_json())
    from_zero = {**data, "delay_lower": [0.0, 0.0]}  # claims delays from 0: not what was proven
    with pytest.raises(ValueError, match="assumptions"):
        load_certificate(json.dumps(from_zero))
    from_zero["assumptions"] = list(lmi_assumptions(parse_gain_variation("frozen")))
    with pytest.raises(ValueError, match="proof is for delays from"):
        load_certificate(json.dumps(from_zero))
    with pytest.raises(ValueError, match="delay_lower"):
        load_certificate(json.dumps({**data, "delay_lower": [-1.0, 0.0]}))


def test_an_interval_certificate_is_refused_for_profiles_that_fall_below_it(one_joint,
                                                                          with_floor):
    with_floor.check(one_joint, 1.0, 1.0, (0.5, FLOOR))
    with pytest.raises(ValueError, match=r"backward delay can fall to 0\.2 s, below"):
        with_floor.check(one_joint, 1.0, 1.0, (0.5, 0.2))
    with pytest.raises(ValueError, match="below the certificate's minimum delay"):
        with_floor.check(one_joint, 1.0, 1.0)  # no declared floor: the delay may reach 0


PROFILES = [
    FourierDelay(np.array([0.5, 0.8])),
    ConstantDelay(np.array([0.3, 0.7])),
    SinusoidalDelay(0.6, 0.2, 1.3, np.array([0.0, 1.0])),
    SwitchingDelay(0.2, 0.9, dwell=0.05, batch=3),
    TraceDelay(np.array([0.0, 1.0, 2.0]), np.array([0.4, 0.25, 0.6])),
    PiecewiseDelay(np.array([[0.0, 1.0]]), np.array([[0.7, 0.35]])),
    SquareWaveDelay(np.array([0.3]), np.array([0.8]), np.array([0.1]), np.array([0.0])),
]


@pytest.mark.parametrize("profile", [*PROFILES, scale_delay(PROFILES[5], 2.0),
                                     stack_delays([ConstantDelay(0.6), FourierDelay(0.5)])],
                         ids=lambda p: type(p).__name__)
def test_every_profile_stays_above_its_declared_floor(profile):
    values = profile.sample(np.linspace(0.0, 40.0, 40001))
    floor = delay_floor(profile)
    assert 0.0 <= floor <= values.min() + 1e-12
    assert values.min() - floor < 0.01 * profile.bound  # tight, not just 0


def test_paper_scenarios_stay_above_their_floor():
    scenario = paper_scenarios(3, batch=8)
    assert delay_floor(scenario.forward) >= PAPER_DELAY_FLOOR
    assert 0.451 < PAPER_DELAY_FLOOR < 0.452


@pytest.mark.parametrize(("args", "needle"), [
    (["--tl-min", "1"],
     "'--tl-min': the minimum delay T_l_min = 1 s is not below the bound T_l* = 1 s"),
    (["--tr-min", "-0.1"], "--tr-min"),
    (["--tr-min", "nan"], "--tr-min"),
])
def test_certify_refuses_bad_minimum_delays(capsys, args, needle):
    assert main(["certify", "--kr", "5:10", "--br", "30:60", *args]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], lines


def test_the_cache_reuses_a_verified_certificate_and_recomputes_an_edited_one(tmp_path,
                                                                             one_joint,
                                                                             with_floor):
    from teleopkit.certification.cache import cached
    from teleopkit.certification.question import Question

    key = Question(one_joint, NARROW, (1.0, 1.0), (FLOOR, FLOOR)).key("lmi")
    assert key != Question(one_joint, NARROW, (1.0, 1.0)).key("lmi")
    assert key != Question(one_joint, NARROW, (1.0, 1.0), (FLOOR, FLOOR)).key("nuno")
    calls = []

    def compute():
        calls.append(1)
        return with_floor

    first, reused = cached(key, compute, tmp_path)
    again, reused_again = cached(key, compute, tmp_path)
    assert (reused, reused_again, len(calls)) == (False, True, 1)
    assert again.to_json() == first.to_json()
    path = tmp_path / f"{key}.json"
    data = json.loads(path.read_text())
    data["polytope"]["h"][0] *= 2.0  # an edited file is not trusted: recomputed, overwritten
    path.write_text(json.dumps(data))
    _, reused = cached(key, compute, tmp_path)
    assert not reused and len(calls) == 2
    assert load_certificate(path.read_text()).to_json() == with_floor.to_json()
