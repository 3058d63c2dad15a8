"""Tests of teleopkit.certification.nuno.lyapunov: the scheduled storage along nonlinear runs."""

from __future__ import annotations

import numpy as np
import pytest
from scheduled_helpers import PASSIVE, SHAPED, adversarial
from scipy.integrate import cumulative_simpson

from teleopkit.certification.nuno.lyapunov import ScheduledStorage, double_integral
from teleopkit.delays import ConstantDelay
from teleopkit.model.params import paper_setup
from teleopkit.sim import Scenario, Simulator, StateLayout


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
