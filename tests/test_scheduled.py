"""The scheduled gain classes: the storage along nonlinear runs, the layer, the certificate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.integrate import cumulative_simpson

from teleopkit.certification import (
    GainBox,
    GainCertificate,
    certify_gains,
    check_certificate,
    load_certificate,
)
from teleopkit.certification.nuno.lyapunov import ScheduledStorage, double_integral
from teleopkit.delays import ConstantDelay, SwitchingDelay
from teleopkit.model.params import Operator, PDGains, paper_setup
from teleopkit.rl.torch_projection import torch_projection
from teleopkit.safety import CertifiedLoop, SafetyLayer
from teleopkit.safety.factory import layer_for
from teleopkit.sim import Scenario, Simulator, StateLayout

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
PASSIVE = dataclasses.replace(paper_setup(), operator=Operator(amplitudes=(0.0, 0.0)),
                              torque_limit=math.inf)
"""The paper's plant with the operator holding the origin (passive) and no torque saturation."""
SHAPED = dataclasses.replace(PASSIVE, local_gains=PDGains((25.0, 15.0), (10.0, 8.0)))
"""Different local gains per joint: the common shape is then (1, 0.6)."""


def adversarial(params, batch: int = 6, seed: int = 0) -> Simulator:
    """Delays jumping between 0 and 1 s every 50-70 ms, both channels independently."""
    return Simulator(Scenario(params, SwitchingDelay(0.0, 1.0, 0.06, "extremes", seed, batch),
                              SwitchingDelay(0.0, 1.0, 0.05, "extremes", seed + 1, batch),
                              np.ones((batch, params.n_joints))))


def schedule(storage: ScheduledStorage, kappa: np.ndarray, rng, on_boundary: float = 0.2):
    """Gains of the class for ``kappa`` (P, B): common shape, damping random in the cone."""
    shape, cone = np.array(storage.shape), np.array(storage.cone)
    stiffness = kappa[..., None] * shape
    damping = cone * stiffness * rng.uniform(1.0, 3.0, stiffness.shape)
    damping = np.where(rng.random(damping.shape) < on_boundary, cone * stiffness, damping)
    return np.concatenate([stiffness, damping], axis=-1)


@pytest.mark.parametrize("params", [PASSIVE, SHAPED], ids=["paper", "shaped"])
def test_storage_never_rises_when_kappa_does_not_fall(params, rng):
    storage = ScheduledStorage.for_plant(params, 1.0, 1.0)
    sim = adversarial(params)
    kappa = np.maximum.accumulate(1.0 + 40 * rng.random((1500, 6)) * (rng.random((1500, 6))
                                                                      < 0.02), axis=0)
    value = storage.value(params, sim.run(15.0, schedule(storage, kappa, rng)))
    rise = np.diff(value, axis=0) / value[:-1]
    assert rise.max() < 1e-7  # falls at every sample, to integration accuracy
    assert value[-1].max() < 0.5 * value[0].min()


def test_storage_rises_under_arbitrary_stiffness_switching(rng):
    storage = ScheduledStorage.for_plant(PASSIVE, 1.0, 1.0)
    kappa = rng.uniform(1.0, 50.0, (1000, 6))
    value = storage.value(PASSIVE, adversarial(PASSIVE).run(10.0, schedule(storage, kappa, rng)))
    assert (value / value[0]).max() > 2.0  # outside the class the storage is no certificate


def test_a_fall_of_kappa_raises_the_storage_by_at_most_its_ratio(rng):
    storage = ScheduledStorage.for_plant(PASSIVE, 1.0, 1.0)
    gains = schedule(storage, rng.uniform(1.0, 50.0, (800, 6)), rng)
    trajectory = adversarial(PASSIVE).run(8.0, gains)
    value = storage.value(PASSIVE, trajectory)
    kappa = storage.kappa(np.concatenate([trajectory.gains[1:], trajectory.gains[-1:]]))
    ratio = np.maximum(1.0, kappa[:-1] / kappa[1:])
    assert (value[1:] / (value[:-1] * ratio)).max() <= 1.0 + 1e-7


def test_energy_integrals_are_the_integrals_of_the_squared_velocities():
    """The simulator's integrals against Simpson's rule on its own velocities, recorded finely."""
    scenario = Scenario(paper_setup(), ConstantDelay(0.3), ConstantDelay(0.3), np.ones((2, 2)))
    step = 0.00125 / 8
    run = Simulator(scenario, dt=step, control_period=step).run(
        2.0, np.array([10.0, 10.0, 30.0, 30.0]))
    layout = StateLayout(2)
    for speed, single, double in (("dql", "int_dql2", "iint_dql2"),
                                  ("dtheta", "int_dtheta2", "iint_dtheta2")):
        v2 = layout.get(run.state, speed) ** 2
        integral = cumulative_simpson(v2, dx=step, axis=0, initial=0.0)
        np.testing.assert_allclose(layout.get(run.state, single), integral, rtol=1e-5,
                                   atol=1e-7 * integral.max())
        twice = cumulative_simpson(integral, dx=step, axis=0, initial=0.0)
        np.testing.assert_allclose(layout.get(run.state, double), twice, rtol=1e-5,
                                   atol=1e-7 * twice.max())


def test_double_integral_matches_its_definition():
    t = np.linspace(0.0, 4.0, 401)
    v2 = np.sin(3 * t) ** 2 + 0.1
    single = np.concatenate([[0.0], np.cumsum(0.5 * (v2[1:] + v2[:-1]) * np.diff(t))])
    double = np.concatenate([[0.0], np.cumsum(0.5 * (single[1:] + single[:-1]) * np.diff(t))])
    got = double_integral(t, single, double, 1.234)
    for k in (50, 200, 400):  # int_{t-T}^t (s - t + T) v^2(s) ds
        s = np.linspace(max(0.0, t[k] - 1.234), t[k], 20001)
        w = np.interp(s, t, v2) * (s - t[k] + 1.234)
        assert got[k] == pytest.approx(np.trapezoid(w, s), rel=2e-3)


def certified(variation: str, params=PASSIVE) -> GainCertificate:
    return certify_gains(params, BOX, 1.0, 1.0, "nuno", variation)


def run_loop(layer: SafetyLayer, sim: Simulator, steps: int, rng, high: float = 200.0):
    """Random raw actions through the certified loop: the trajectory and the levels."""
    loop = CertifiedLoop(layer)
    trajectory, levels = loop.run(sim, rng.uniform(-10.0, high, (steps, sim.batch, 4)))
    assert loop.unsafe_actions == 0
    return trajectory, levels


@pytest.mark.parametrize("budget", [0.0, 0.5, 2.0])
def test_the_budget_bounds_the_storage_along_any_raw_actions(budget, rng):
    layer = layer_for(certified(f"scheduled:{budget:g}"))
    trajectory, levels = run_loop(layer, adversarial(PASSIVE, seed=3), 800, rng)
    assert levels.min() >= -1e-12 and levels.max() <= budget
    kappa = layer.certificate.storage.kappa(trajectory.gains)
    falls = np.log(np.maximum(1.0, kappa[1:-1] / kappa[2:])).sum(axis=0)
    np.testing.assert_allclose(falls, budget - levels[-1], atol=1e-9)
    assert np.all(np.diff(levels, axis=0) <= 1e-15)  # a budget is only ever spent
    value = layer.certificate.storage.value(PASSIVE, trajectory)
    assert (value / value[0]).max() <= math.exp(budget) * (1 + 1e-7)


def test_the_tank_keeps_storage_plus_tank_from_rising(rng):
    layer = layer_for(certified("tank:0.05"))
    trajectory, levels = run_loop(layer, adversarial(PASSIVE, seed=5), 1000, rng)
    value = layer.certificate.storage.value(PASSIVE, trajectory)
    total = value + levels  # just after each sample, its jump paid
    assert (np.diff(total, axis=0) / total[:-1]).max() < 1e-7
    assert levels.min() >= -1e-12
    kappa = layer.certificate.storage.kappa(trajectory.gains)
    assert np.any(kappa[2:] < kappa[1:-1] - 1e-6)  # the tank did pay for falls


def test_the_shaped_plant_keeps_its_common_shape(rng):
    layer = layer_for(certified("scheduled:1", SHAPED))
    trajectory, _ = run_loop(layer, adversarial(SHAPED, seed=7), 300, rng)
    gains = trajectory.gains
    np.testing.assert_allclose(gains[..., 1], 0.6 * gains[..., 0], rtol=1e-12)
    value = layer.certificate.storage.value(SHAPED, trajectory)
    assert (value / value[0]).max() <= math.e * (1 + 1e-7)


raw_actions = arrays(np.float64, 4, elements=st.floats(-300.0, 400.0))


@settings(deadline=None, max_examples=150)
@given(st.lists(raw_actions, min_size=1, max_size=6))
def test_projection_matches_the_qp_at_every_step(sequence):
    layer = layer_for(certified("scheduled:0.7"))
    for raw in sequence:
        result = layer.step(raw)
        expected = layer.project_qp(raw, floor=float(layer.last_floor[0]))
        np.testing.assert_allclose(result.action, expected, rtol=0, atol=1e-6)
        assert layer.contains(result.action[None]).all()


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e300, -1e300])
def test_projection_is_total(bad):
    layer = layer_for(certified("scheduled:0.3"))
    first = layer.step(np.array([bad, 10.0, 30.0, 30.0]))
    assert layer.contains(first.action[None]).all()
    second = layer.step(np.array([20.0, 20.0, bad, 60.0]))
    assert layer.contains(second.action[None]).all()
    if not math.isfinite(bad) or abs(bad) > 1e299:
        assert second.action[0] >= first.action[0] * math.exp(-0.3) - 1e-12


def test_the_layer_keeps_its_own_history():
    layer = layer_for(certified("scheduled:1"))
    first = layer.step(np.array([40.0, 40.0, 140.0, 140.0]))
    second = layer.step(np.array([5.0, 5.0, 30.0, 30.0]))  # a fall: spends the budget
    assert second.action[0] == pytest.approx(first.action[0] * math.exp(-1.0))
    with pytest.raises(ValueError, match="episode has 1 scenarios"):
        layer.step(np.ones((3, 4)))
    layer.reset()
    assert layer.step(np.ones((3, 4))).action.shape == (3, 4)


@pytest.mark.parametrize("variation", ["scheduled:0.4", "tank:0.02"])
def test_torch_projection_is_the_layers_projection_at_every_step(variation, rng):
    """The actor is trained through the step's set: floor from the observed run-time state."""
    layer = layer_for(certified(variation))
    loop = CertifiedLoop(layer)
    loop.start(adversarial(PASSIVE, batch=4))
    projection = torch_projection(layer)
    for _ in range(60):
        raw = rng.uniform(-20.0, 200.0, (4, 4))
        state = layer.run_time_state(4)
        obs = torch.as_tensor(np.concatenate([np.zeros((4, 14)), state], axis=1))
        expected = projection(torch.as_tensor(raw), obs).numpy()
        _, applied = loop.step(raw)
        np.testing.assert_allclose(applied.action, expected, rtol=1e-10, atol=1e-9)


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
