"""Parameter validation: bad values fail at construction with a message naming the field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleopkit import (
    ElasticJoints,
    Operator,
    PDGains,
    PlanarArm,
    Scenario,
    Simulator,
    TeleoperatorParams,
    Wall,
    paper_scenarios,
    paper_setup,
)


def test_paper_setup_values():
    p = paper_setup()
    assert p.local_arm.lengths == (0.38, 0.38) and p.remote_arm.masses == (0.5, 0.35)
    assert p.joints.stiffness == (100.0, 100.0) and p.joints.rotor_inertia == (0.3, 0.3)
    assert p.local_gains == PDGains((25.0, 25.0), (10.0, 10.0))
    assert (p.operator.stiffness, p.operator.damping) == (10.0, 2.0)
    assert p.initial.local == (-0.2, 0.2) and p.initial.remote == (-0.1, 0.1)
    assert p.torque_limit == 300.0


@pytest.mark.parametrize(("build", "message"), [
    (lambda: PlanarArm((0.3, -0.1), (1.0, 1.0)), "arm lengths"),
    (lambda: PlanarArm((0.3, 0.3), (1.0, math.nan)), "arm masses"),
    (lambda: PlanarArm((0.3, 0.3), (1.0,)), "one per joint"),
    (lambda: PlanarArm((), ()), "empty"),
    (lambda: ElasticJoints((100.0, 0.0)), "joint stiffness"),
    (lambda: ElasticJoints((100.0, 100.0), (0.3, -1.0)), "rotor inertia"),
    (lambda: PDGains((-1.0, 1.0), (1.0, 1.0)), "proportional gain"),
    (lambda: PDGains((1.0, 1.0), (math.nan, 1.0)), "damping gain"),
    (lambda: PDGains((1.0, 1.0), (math.inf, 1.0)), "damping gain"),
    (lambda: Operator(stiffness=-1.0), "operator stiffness"),
    (lambda: Wall((0.1, math.nan)), "wall position"),
    (lambda: Wall(stiffness=-5.0), "wall stiffness"),
    (lambda: TeleoperatorParams(torque_limit=0.0), "torque limit"),
    (lambda: TeleoperatorParams(torque_limit=math.nan), "torque limit"),
    (lambda: TeleoperatorParams(remote_arm=PlanarArm((1.0,), (1.0,))), "remote arm"),
    (lambda: TeleoperatorParams(environment="water"), "environment"),
    (lambda: Scenario(reference_gains=np.ones((1, 3))), "reference gains"),
])
def test_bad_parameters_are_refused(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_parameters_are_frozen():
    p = paper_setup()
    with pytest.raises(AttributeError):
        p.torque_limit = 5.0  # type: ignore[misc]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"dt": 0.0}, "integration step"),
    ({"dt": math.nan}, "integration step"),
    ({"dt": 0.003}, "multiple"),
    ({"backend": "gpu"}, "backend"),
])
def test_bad_simulator_settings_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Simulator(paper_scenarios(0), **kwargs)


@pytest.mark.parametrize("gains", [[10, 10, -30, 30], [10, 10, np.nan, 30], [10, 10, 30],
                                   [[10, 10, 30, np.inf]]])
def test_bad_gains_are_refused(gains):
    sim = Simulator(paper_scenarios(0))
    with pytest.raises(ValueError, match="remote gains"):
        sim.advance(np.array(gains, dtype=float))
    assert sim.time == 0.0
