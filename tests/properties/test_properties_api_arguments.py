"""Arguments of the public API: a wrong shape, value or type is refused in one line naming it.

Each case asserts the exception type (``ValueError`` for a bad value, ``TypeError`` for a wrong
type) and that the message names the argument, with no numpy or attribute error in between.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import teleopkit as tk
from teleopkit.certification import certify_gains, load_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.delays.profiles import ConstantDelay, FourierDelay, TraceDelay
from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    paper_setup,
)
from teleopkit.setup import Setup
from teleopkit.sim.scenarios import paper_scenarios
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.timing import periods, substeps

GAINS = [10.0, 10.0, 30.0, 30.0]
BOX = GainBox.uniform((5.0, 10.0), (30.0, 60.0))


def _raises(call: Callable[[], object], kind: type[Exception], *words: str) -> str:
    """The one-line message of ``kind`` that ``call`` raises, checked to hold every word."""
    with pytest.raises(kind) as error:
        call()
    message = str(error.value)
    assert type(error.value) is kind, message
    assert "\n" not in message
    for word in words:
        assert word in message, message
    return message


# 3. gains for another batch


@pytest.fixture(scope="module")
def batch_of_four() -> Simulator:
    return Simulator(paper_scenarios(0, batch=4))


@pytest.mark.parametrize("entry", ["run", "advance"])
@pytest.mark.parametrize("shape", [(3, 4), (2, 3, 4), (1, 1, 4, 4), (2, 2, 4, 4)])
def test_gains_for_another_batch_are_refused_naming_their_shape(batch_of_four, entry, shape):
    gains = np.broadcast_to(np.array(GAINS), shape)
    call = ((lambda: batch_of_four.run(2.0, gains=gains)) if entry == "run"
            else (lambda: batch_of_four.advance(gains)))
    message = _raises(call, ValueError, "remote gains", "B = 4", f"got {shape}")
    assert "broadcast" not in message


@pytest.mark.parametrize("shape", [(4,), (1, 4), (4, 4), (3, 1, 4), (3, 4, 4)])
def test_gains_of_every_documented_shape_are_accepted(shape):
    sim = Simulator(paper_scenarios(0, batch=4))
    result = sim.advance(np.broadcast_to(np.array(GAINS), shape))
    assert result.state.shape[1] == 4


def test_a_schedule_for_another_batch_is_refused_by_run():
    sim = Simulator(paper_scenarios(0, batch=4))
    schedule = np.broadcast_to(np.array(GAINS), (200, 3, 4))
    _raises(lambda: sim.run(2.0, gains=schedule), ValueError, "remote gains", "got (200, 3, 4)")


# 4. control period and seed


@pytest.mark.parametrize("period", [0.0, -0.01, math.nan, math.inf])
def test_a_control_period_that_is_no_time_is_refused(period):
    _raises(lambda: tk.simulate((5.0, 30.0), duration=1.0, delay=0.2, control_period=period),
            ValueError, "control period must be positive and finite")


@pytest.mark.parametrize("call", [lambda: periods(1.0, "0.01"), lambda: substeps(0.01, None),
                                  lambda: periods(None)])
def test_a_time_that_is_no_number_is_a_type_error(call):
    message = _raises(call, TypeError, "must be a number of seconds")
    assert re.match(r"^(control period|integration step|duration) ", message)


@pytest.mark.parametrize("call", [
    lambda: tk.simulate((5.0, 30.0), duration=0.1, delay=0.2, seed=-1),
    lambda: Setup.paper().scenarios(-1, 2),
    lambda: Setup.paper().scenarios(np.int64(-3), 1),
    lambda: tk.paper_scenarios(-1, batch=2),
])
def test_a_negative_seed_is_refused_naming_it(call):
    message = _raises(call, ValueError, "seed must be a non-negative integer")
    assert "expected non-negative integer" not in message


@pytest.mark.parametrize("seed", [1.5, "1", True, None, [1, 2]])
def test_a_seed_that_is_no_integer_is_a_type_error(seed):
    _raises(lambda: Setup.paper().scenarios(seed, 1), TypeError, "seed", type(seed).__name__)


def test_a_seed_of_simulate_that_is_no_integer_is_a_type_error():
    _raises(lambda: tk.simulate((5.0, 30.0), duration=0.1, delay=0.2, seed=1.5), TypeError,
            "seed must be a non-negative integer", "float")


def test_a_generator_or_a_numpy_integer_still_seeds_the_scenarios():
    setup = Setup.paper()
    by_generator = setup.scenarios(np.random.default_rng(7), 2)
    by_seed, by_numpy = setup.scenarios(7, 2), setup.scenarios(np.int64(7), 2)
    np.testing.assert_array_equal(by_generator.reference_gains, by_seed.reference_gains)
    np.testing.assert_array_equal(by_numpy.reference_gains, by_seed.reference_gains)


# 5. arguments of the wrong type


@pytest.mark.parametrize(("call", "words"), [
    (lambda: tk.simulate((5.0, 30.0), duration=0.1, setup="paper"),
     ("setup must be a Setup", "Setup.paper()", "Setup.from_file(", "got str")),
    (lambda: tk.simulate((5.0, 30.0), duration=0.1, params="paper"),
     ("params must be a TeleoperatorParams", "got str")),
    (lambda: Setup.from_params(Setup.paper()), ("params must be a TeleoperatorParams", "Setup")),
    (lambda: certify_gains("paper", BOX), ("params must be a TeleoperatorParams", "got str")),
    (lambda: certify_gains(paper_setup(), ((5, 10), (30, 60))),
     ("box must be a GainBox", "GainBox.uniform(", "got tuple")),
    (lambda: Simulator(None), ("scenario must be a Scenario", "got NoneType")),
])
def test_an_argument_of_the_wrong_type_is_a_type_error_naming_it(call, words):
    message = _raises(call, TypeError, *words)
    assert "has no attribute" not in message


# 6. gain ranges that are not (min, max) pairs


@pytest.mark.parametrize(("kr", "br", "kind", "shown"), [
    (5.0, (30, 60), TypeError, "K_r range must be a (min, max) pair, got 5.0"),
    ("1:5", (30, 60), TypeError, "K_r range must be a (min, max) pair, got '1:5'"),
    ("15", (30, 60), TypeError, "K_r range must be a (min, max) pair, got '15'"),
    ((1, 2, 3), (30, 60), ValueError, "K_r range must be a (min, max) pair, got (1, 2, 3)"),
    ((1,), (30, 60), ValueError, "K_r range must be a (min, max) pair, got (1,)"),
    ((1, 5), None, TypeError, "B_r range must be a (min, max) pair, got None"),
    ((1, 5), (30, "x"), TypeError, "B_r range must be a (min, max) pair, got (30, 'x')"),
])
def test_a_uniform_range_that_is_no_pair_is_refused_naming_it(kr, br, kind, shown):
    message = _raises(lambda: GainBox.uniform(kr, br), kind, shown)
    assert "unpack" not in message and "iterable" not in message


def test_ranges_that_are_not_one_pair_per_joint_are_refused():
    _raises(lambda: GainBox(5.0, ((30, 60),)), TypeError, "K_r ranges", "one (min, max) pair")
    _raises(lambda: GainBox(((1, 5),), "30:60"), TypeError, "B_r ranges", "got str")
    _raises(lambda: GainBox((5.0,), ((30, 60),)), TypeError, "K_r range must be a (min, max) pair")
    assert GainBox.uniform(np.array([1.0, 5.0]), [30, 60]).kr == ((1.0, 5.0), (1.0, 5.0))


# 7. a declared bound below the profile's own values


@pytest.mark.parametrize(("build", "words"), [
    (lambda: TraceDelay(np.array([0.0, 1.0, 2.0]), np.array([0.1, 0.5, 0.3]), bound=0.4),
     "TraceDelay reaches 0.5 s, above its declared bound 0.4 s"),
    (lambda: ConstantDelay(0.5, bound=0.3),
     "ConstantDelay reaches 0.5 s, above its declared bound 0.3 s"),
    (lambda: ConstantDelay(np.array([0.1, 0.5]), bound=0.3),
     "ConstantDelay reaches 0.5 s, above its declared bound 0.3 s"),
    (lambda: FourierDelay(np.array([0.5, 1.0]), bound=0.9),
     "FourierDelay reaches 1 s, above its declared bound 0.9 s"),
])
def test_a_bound_below_the_profile_is_refused_by_its_constructor(build, words):
    _raises(build, ValueError, words)


def test_a_bound_at_or_above_the_profile_is_accepted():
    assert TraceDelay(np.array([0.0, 1.0]), np.array([0.1, 0.5]), bound=0.5).bound == 0.5
    assert ConstantDelay(0.5, bound=1.0).bound == 1.0
    assert ConstantDelay(0.5).bound == 0.5 and FourierDelay(0.8).bound == 0.8
    assert FourierDelay(0.8, bound=0.8).sample(np.linspace(0.0, 5.0, 50)).max() <= 0.8


# 11. certificates read from a path


@pytest.fixture(scope="module")
def certificate_json() -> str:
    return certify_gains(paper_setup(), BOX, method="nuno").to_json()


@pytest.mark.parametrize("name", ["nonexistent.json", "certificates/nonexistent"])
def test_a_missing_certificate_file_is_named(tmp_path, monkeypatch, name):
    monkeypatch.chdir(tmp_path)
    for source in (name, str(tmp_path / name), tmp_path / name, Path(name)):
        message = _raises(lambda source=source: load_certificate(source), ValueError,
                          f"no such certificate file: {source}")
        assert "Expecting value" not in message


def test_a_certificate_is_read_from_its_path_or_its_text(tmp_path, monkeypatch, certificate_json):
    monkeypatch.chdir(tmp_path)
    expected = load_certificate(certificate_json).to_dict()
    for name in ("certificate.json", "certificate"):
        (tmp_path / name).write_text(certificate_json)
        for source in (name, str(tmp_path / name), tmp_path / name):
            assert load_certificate(source).to_dict() == expected
    assert load_certificate("\n  " + certificate_json).to_dict() == expected


@pytest.mark.parametrize("text", ["not json", "", "[1, 2]", '{"certified": true}'])
def test_text_that_is_no_path_is_still_parsed_as_json(tmp_path, monkeypatch, text):
    monkeypatch.chdir(tmp_path)
    _raises(lambda: load_certificate(text), ValueError, "malformed gain certificate")


def test_an_unreadable_certificate_path_or_type_is_named(tmp_path):
    _raises(lambda: load_certificate(str(tmp_path)), ValueError, "cannot read certificate file",
            str(tmp_path))
    _raises(lambda: load_certificate(None), TypeError, "text must be", "got NoneType")
    _raises(lambda: load_certificate({"box": {}}), TypeError, "text must be", "got dict")


# 12. per-joint fields of different lengths name both fields


@pytest.mark.parametrize(("build", "words"), [
    (lambda: ElasticJoints(stiffness=(100.0,)),
     "joint stiffness and rotor inertia need one per joint, got 1 and 2 values"),
    (lambda: ElasticJoints(rotor_inertia=(0.3,)),
     "joint stiffness and rotor inertia need one per joint, got 2 and 1 values"),
    (lambda: PDGains(stiffness=(25.0,)),
     "proportional gain and damping gain need one per joint, got 1 and 2 values"),
    (lambda: PlanarArm(lengths=(0.38,)),
     "arm lengths and arm masses need one per joint, got 1 and 2 values"),
    (lambda: PlanarArm(com=(0.1, 0.2, 0.3)),
     "arm lengths and arm com need one per joint, got 2 and 3 values"),
    (lambda: Operator(amplitudes=(3.0,)),
     "operator amplitudes and operator frequencies need one per joint, got 1 and 2 values"),
    (lambda: InitialState(local=(0.1,)),
     "initial local position and initial remote position need one per joint, got 1 and 2 values"),
])
def test_per_joint_fields_of_different_lengths_name_both(build, words):
    message = _raises(build, ValueError, words)
    assert not re.search(r"(needs|got) 1 values", message)


def test_one_joint_of_a_two_joint_plant_is_counted_in_the_singular():
    one = ElasticJoints((100.0,), (0.3,))
    message = _raises(lambda: TeleoperatorParams(joints=one), ValueError,
                      "elastic joints has 1 joint, the local arm 2")
    assert "1 joints" not in message


def test_a_scalar_still_fills_every_joint():
    assert ElasticJoints((100.0, 50.0), 0.3).rotor_inertia == (0.3, 0.3)
    assert PDGains(25.0, 10.0) == PDGains((25.0,), (10.0,))
