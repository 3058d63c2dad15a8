"""The simulator refuses exactly the steps its method cannot integrate stably."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from teleopkit import ConstantDelay, PlanarArm, Scenario, Simulator
from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    PDGains,
    TeleoperatorParams,
    Wall,
    paper_setup,
)
from teleopkit.sim import simulator as simulator_module
from teleopkit.sim.stability import (
    ACCURATE_FRACTION,
    accurate_step,
    amplification,
    check_step,
    largest_motor_damping,
    local_damping_rate,
    local_mode,
    remote_mode,
)
from teleopkit.sim.tableau import REAL_STABILITY_LIMIT

LIGHT = replace(paper_setup(), local_arm=PlanarArm((0.38, 0.38), (0.25, 0.175)))
"""The paper's teleoperator with a local arm half as heavy: its damping twice as fast."""


def _scenario(params) -> Scenario:
    return Scenario(params, ConstantDelay(0.2), ConstantDelay(0.2), np.array([[1.0, -0.7]]))


def _rate_at(params, q2: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of ``M_l(q)^-1 diag(K_d + B_l)`` at each ``q_2``, by numpy's eig."""
    damping = np.diag(np.asarray(params.local_gains.damping) + params.operator.damping)
    q = np.stack([np.zeros_like(q2), q2], axis=1)
    return np.array([np.linalg.eigvals(np.linalg.solve(m, damping)).real.max()
                     for m in mass_matrix(params.local_arm, q)])


def test_two_link_rate_is_the_stretched_arms_and_bounds_every_configuration():
    rate = local_damping_rate(paper_setup())
    assert rate == pytest.approx(_rate_at(paper_setup(), np.zeros(1))[0], rel=1e-12)
    sampled = _rate_at(paper_setup(), np.random.default_rng(0).uniform(-math.pi, math.pi, 2000))
    assert sampled.max() <= rate * (1 + 1e-12)
    assert rate == pytest.approx(1030.15, abs=0.01)  # the paper's arm
    assert local_damping_rate(LIGHT) == pytest.approx(2 * rate, rel=1e-12)


def test_the_default_step_is_inside_the_limit_on_the_paper_model():
    assert local_damping_rate(paper_setup()) * 0.0025 < REAL_STABILITY_LIMIT
    assert largest_motor_damping(paper_setup(), 0.0025) > 150.0  # the paper's B_r range


def test_a_step_beyond_the_limit_is_refused_in_one_line():
    with pytest.raises(ValueError, match="stability limit") as error:
        Simulator(_scenario(LIGHT), dt=0.0025)
    assert "\n" not in str(error.value) and "at most 1.644 ms" in str(error.value)
    assert "dt = 1.25 ms (8 steps per control period) also keeps its accuracy" in str(error.value)
    Simulator(_scenario(LIGHT), dt=0.00125)  # 2.58 of 3.39: accepted


def test_the_refused_step_really_is_unstable(monkeypatch):
    """Past the limit the run is wrong, not loud: the saturated torques keep it bounded."""
    def positions(dt: float) -> np.ndarray:
        sim = Simulator(_scenario(LIGHT), dt=dt)
        return sim.run(2.0).state[:, 0, sim.layout.positions]

    converged = positions(0.0003125)
    assert np.abs(positions(0.00125) - converged).max() < 1e-4
    monkeypatch.setattr(simulator_module, "check_step", lambda *args: None)
    assert np.abs(positions(0.0025) - converged).max() > 0.05


def test_motor_damping_beyond_the_limit_is_refused():
    sim = Simulator(_scenario(paper_setup()))
    largest = largest_motor_damping(paper_setup(), sim.dt)
    sim.advance(np.array([10.0, 10.0, 0.99 * largest, 30.0]))
    with pytest.raises(ValueError, match="remote damping B_r") as error:
        sim.advance(np.array([10.0, 10.0, 30.0, 1.01 * largest]))
    # 410 on a 0.3 rotor: 1367 1/s; 0.85 of the limit wants 2.1 ms, so 2 ms (5 steps)
    assert "dt = 2 ms integrates it stably and accurately" in str(error.value)
    with pytest.raises(ValueError, match="remote damping B_r"):
        sim.run(0.1, np.array([10.0, 10.0, 30.0, 1.01 * largest]))


@pytest.mark.parametrize(("damping", "step"), [(10.0, 0.0025), (12.0, 0.002), (6.0, 0.0025)])
def test_the_accurate_step_keeps_1e5_rad_where_the_stable_step_loses_it(damping, step):
    """Within 0.85 of the limit the default method stays within 1e-5 rad over 20 s; local
    ``B_l = 12`` puts 2.5 ms at 0.89 of it, stable but over 1e-5 rad off, and 2 ms is proposed."""
    params = replace(paper_setup(), local_gains=PDGains((25.0, 25.0), (damping, damping)))
    assert accurate_step(params) == pytest.approx(step, rel=1e-12)
    rate = local_damping_rate(params)
    assert rate * step <= ACCURATE_FRACTION * REAL_STABILITY_LIMIT

    def positions(dt: float) -> np.ndarray:
        sim = Simulator(_scenario(params), dt=dt)
        return sim.run(20.0, chunk=20.0).state[:, 0, sim.layout.positions]

    converged = positions(0.000125)
    assert np.abs(positions(step) - converged).max() < 1e-5
    if step < 0.0025:
        assert np.abs(positions(0.0025) - converged).max() > 1e-5


# --- the remote arm's springs: elastic joints and a wall in contact ---------------------------

WALLED = replace(paper_setup(), environment=Wall((0.5, math.inf), 1e9, 5.0),
                 initial=InitialState((0.8, 0.0), (0.45, 0.0), (0.55, 0.0)))
"""The trial's wall: 1e9 N m/rad at 0.5 rad on the first joint, the link starting just short of
it and pulled into it."""


def _with_wall(stiffness: float) -> TeleoperatorParams:
    return replace(WALLED, environment=replace(WALLED.environment, stiffness=stiffness))


def _coupled_modes(params: TeleoperatorParams, contact: bool) -> np.ndarray:
    """Every eigenvalue of the remote links, rotors, joint springs and wall, at each ``q_2``."""
    n = params.n_joints
    q = np.stack([np.zeros(721), np.linspace(-math.pi, math.pi, 721)], axis=1)
    wall = params.environment if contact else None
    touching = np.isfinite(wall.position) if wall is not None else np.zeros(n, bool)
    spring = np.diag(params.joints.stiffness)
    stiffness = np.block([[spring + np.diag(touching * (wall.stiffness if wall else 0.0)),
                           -spring], [-spring, spring]])
    damping = np.zeros((2 * n, 2 * n))
    damping[:n, :n] = np.diag(touching * (wall.damping if wall else 0.0))
    mass = np.zeros((len(q), 2 * n, 2 * n))
    mass[:, :n, :n] = mass_matrix(params.remote_arm, q)
    mass[:, n:, n:] = np.diag(params.joints.rotor_inertia)
    inverse = np.linalg.inv(mass)
    system = np.zeros((len(q), 4 * n, 4 * n))
    system[:, :2 * n, 2 * n:] = np.eye(2 * n)
    system[:, 2 * n:, :2 * n] = -inverse @ stiffness
    system[:, 2 * n:, 2 * n:] = -inverse @ damping
    return np.linalg.eigvals(system)


@pytest.mark.parametrize(("params", "contact", "tolerance"), [
    (paper_setup(), False, 1e-9), (_with_wall(1000.0), True, 0.02),
    (replace(paper_setup(), environment=Wall((0.5, 0.5))), True, 0.02),
    (replace(paper_setup(), environment=Wall((math.inf, 0.5), 5000.0, 20.0)), True, 0.02),
])
def test_the_remote_mode_is_the_fastest_coupled_eigenvalue(params, contact, tolerance):
    fastest = np.abs(_coupled_modes(params, contact)).max()
    assert abs(remote_mode(params, contact)) == pytest.approx(fastest, rel=tolerance)
    assert remote_mode(params, contact).real <= 0  # the wall damps, the joints do not


def test_the_paper_model_and_its_default_wall_pass_at_the_default_step():
    check_step(paper_setup(), 0.0025)
    check_step(replace(paper_setup(), environment=Wall((0.5, 0.5))), 0.0025)


def test_a_wall_too_stiff_for_the_step_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"beyond what dt = 2\.5 ms integrates stably") as error:
        Simulator(_scenario(WALLED))
    message = str(error.value)
    assert "\n" not in message and message.startswith("the wall (stiffness 1e+09 N m/rad")
    steps = int(re.search(r"\((\d+) steps per control period\) integrates it", message)[1])
    proposed = 0.01 / steps
    stiffest = float(re.search(r"at most ([0-9.e+]+) N m/rad$", message)[1])
    Simulator(_scenario(WALLED), dt=proposed)  # the step it proposes is accepted
    Simulator(_scenario(_with_wall(stiffest)))  # and so is the wall it proposes
    with pytest.raises(ValueError, match="the wall"):
        Simulator(_scenario(_with_wall(1.05 * stiffest)))


def test_the_refused_wall_really_diverges_and_the_proposed_one_does_not(monkeypatch):
    with pytest.raises(ValueError, match="the wall") as error:
        check_step(WALLED, 0.0025)
    message = str(error.value)
    stiffest = float(re.search(r"at most ([0-9.e+]+) N m/rad$", message)[1])
    monkeypatch.setattr(simulator_module, "check_step", lambda *args: None)
    gains = np.array([10.0, 10.0, 30.0, 30.0])
    refused = Simulator(_scenario(WALLED)).run(1.0, gains)
    assert not np.isfinite(refused.state).all()
    kept = Simulator(_scenario(_with_wall(stiffest))).run(1.0, gains)
    assert np.isfinite(kept.state).all() and np.abs(kept.state[:, 0, :6]).max() < 2.0


def test_stiff_joints_are_refused_and_a_wall_at_minus_inf_is_no_wall():
    stiff = replace(paper_setup(), joints=ElasticJoints((1e9, 1e9), (0.3, 0.3)))
    with pytest.raises(ValueError, match=r"^the elastic joints \(stiffness 1e\+09, 1e\+09"):
        check_step(stiff, 0.0025)
    with pytest.raises(ValueError, match=r"-inf would push at every angle\), got \(-inf, inf\)"):
        Wall((-math.inf, math.inf))
    check_step(replace(paper_setup(), environment=Wall((math.inf, math.inf))), 0.0025)


def test_the_stability_function_is_the_methods():
    z = np.array([-3.38, -1.0, 0.5j, -0.2 + 0.9j])
    assert amplification(z) == pytest.approx(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
                                                    + z**5 / 120 + z**6 / 640), rel=1e-12)
    assert amplification(-REAL_STABILITY_LIMIT) <= 1.0 < amplification(-3.39)


def _stiff_operator(stiffness: float) -> TeleoperatorParams:
    """The paper's teleoperator with an operator spring of ``stiffness`` N m/rad."""
    params = paper_setup()
    return replace(params, operator=replace(params.operator, stiffness=stiffness))


@pytest.mark.parametrize("stiffness", [10.0, 1e4, 1e7])
def test_the_local_mode_is_the_local_arms_fastest_eigenvalue(stiffness):
    """Against numpy's eigenvalues of the local arm's linearised springs and dampers,
    ``[[0, I], [-M^-1 (K_s + K_l), -M^-1 (K_d + B_l)]]``, over its configurations."""
    params = _stiff_operator(stiffness)
    springs = np.diag(np.asarray(params.local_gains.stiffness) + stiffness)
    dampers = np.diag(np.asarray(params.local_gains.damping) + params.operator.damping)
    fastest = 0.0
    for m in mass_matrix(params.local_arm, np.stack([np.zeros(73), np.linspace(-math.pi,
                                                                               math.pi, 73)], 1)):
        inverse = np.linalg.inv(m)
        system = np.block([[np.zeros((2, 2)), np.eye(2)],
                           [-inverse @ springs, -inverse @ dampers]])
        fastest = max(fastest, np.abs(np.linalg.eigvals(system)).max())
    assert abs(local_mode(params)) == pytest.approx(fastest, rel=1e-9)


def test_a_stiff_operator_is_refused_and_the_proposed_step_integrates_it(monkeypatch):
    stiff = _stiff_operator(1e7)
    with pytest.raises(ValueError, match=r"^the local arm's springs \(operator stiffness K_s = "
                                         r"1e\+07 N m/rad") as error:
        check_step(stiff, 0.0025)
    proposed = 0.01 / int(re.search(r"\((\d+) steps per control period\)", str(error.value))[1])
    check_step(stiff, proposed)
    check_step(_stiff_operator(1e4), 0.0025)  # stiff, and still within the default step
    monkeypatch.setattr(simulator_module, "check_step", lambda *args: None)
    gains = np.array([10.0, 10.0, 30.0, 30.0])
    refused = Simulator(_scenario(stiff)).run(0.1, gains)
    assert not np.isfinite(refused.state).all()
    kept = Simulator(_scenario(stiff), dt=proposed).run(0.1, gains)
    assert np.isfinite(kept.state).all()
