"""Tests of teleopkit.safety.schedule: the safety layer of the scheduled gain classes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scheduled_helpers import PASSIVE, SHAPED, adversarial, certified

from teleopkit.safety import CertifiedLoop, SafetyLayer
from teleopkit.safety.factory import layer_for
from teleopkit.sim import Simulator


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
