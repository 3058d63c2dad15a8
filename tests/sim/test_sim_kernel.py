"""The compiled kernel agrees with the readable numpy integrator."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest

from teleopkit import (
    ConstantDelay,
    FourierDelay,
    PlanarArm,
    Scenario,
    Simulator,
    SwitchingDelay,
    Wall,
    paper_scenarios,
)
from teleopkit.delays.profiles import delay_floor
from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    TeleoperatorParams,
)
from teleopkit.sim import kernel
from teleopkit.sim._kernel_reads import delays_exceed
from teleopkit.sim.kernel import LANES
from teleopkit.sim.timing import DEFAULT_DT

THREE_LINK_DT = 0.0005
"""A step inside the method's stability limit for :func:`_three_link`, whose light links and
strong local damping (up to about 4700 1/s) make it five times stiffer than the paper's arm."""


def _three_link() -> TeleoperatorParams:
    arm = PlanarArm((0.3, 0.25, 0.2), (0.6, 0.4, 0.3))
    return TeleoperatorParams(
        local_arm=arm, remote_arm=arm, joints=ElasticJoints((80.0,) * 3, (0.2,) * 3),
        local_gains=PDGains((25.0,) * 3, (10.0,) * 3),
        remote_gains=PDGains((10.0,) * 3, (30.0,) * 3),
        operator=Operator(amplitudes=(1.0, 0.8, 0.5), frequencies=(1.0, 1.5, 2.0),
                          phases=(0.0, 0.1, 0.2), decays=(0.05,) * 3),
        initial=InitialState((0.1, -0.2, 0.3), (0.0, 0.1, -0.1), (0.0,) * 3),
        environment=Wall((0.2, math.inf, 0.1), 500.0, 2.0), torque_limit=8.0)


def _compare(scenario: Scenario, gains: np.ndarray, periods: int, dt: float = DEFAULT_DT,
             ) -> None:
    runs = [Simulator(scenario, dt=dt, backend=b).advance(gains) for b in ("compiled", "numpy")]
    assert runs[0].state.shape[0] == periods
    np.testing.assert_allclose(runs[0].state, runs[1].state, rtol=0, atol=1e-10)
    np.testing.assert_allclose(runs[0].delayed, runs[1].delayed, rtol=0, atol=1e-10)


def test_paper_scenarios_with_changing_gains(rng):
    scenario = paper_scenarios(rng, batch=3)
    gains = rng.uniform(1.0, 50.0, size=(60, 3, 4))
    _compare(scenario, gains, 60)


def test_a_last_block_of_one_scenario(rng):
    # 33 scenarios: a full block of 32 and a block of one, which takes the scalar path
    scenario = paper_scenarios(rng, batch=LANES + 1)
    _compare(scenario, rng.uniform(1.0, 50.0, size=(20, LANES + 1, 4)), 20)


def test_three_links_wall_saturation_and_fast_switching(rng):
    params = _three_link()
    forward = SwitchingDelay(0.0, 0.05, dwell=0.0037, mode="extremes", seed=3, batch=2)
    backward = SwitchingDelay(0.001, 0.03, dwell=0.002, seed=4, batch=2)
    scenario = Scenario(params, forward, backward, rng.uniform(-1, 1, size=(2, 3)))
    _compare(scenario, rng.uniform(0.0, 40.0, size=(80, 2, 6)), 80, THREE_LINK_DT)


def test_one_three_link_scenario_takes_the_serial_kernel(rng):
    # a single scenario runs without the parallel loop, on the generic (Cholesky) path here
    forward = SwitchingDelay(0.0, 0.05, dwell=0.0037, mode="extremes", seed=5, batch=1)
    backward = SwitchingDelay(0.001, 0.03, dwell=0.002, seed=6, batch=1)
    scenario = Scenario(_three_link(), forward, backward, rng.uniform(-1, 1, size=(1, 3)))
    _compare(scenario, rng.uniform(0.0, 40.0, size=(40, 1, 6)), 40, THREE_LINK_DT)


@pytest.mark.parametrize("delay", [0.0, 0.001, 0.0025, 0.013])
def test_short_and_zero_delays(delay):
    scenario = replace(paper_scenarios(5, batch=1), forward=ConstantDelay(delay),
                       backward=ConstantDelay(delay))
    _compare(scenario, np.array([20.0, 15.0, 40.0, 35.0]), 1)
    sims = [Simulator(scenario, backend=b) for b in ("compiled", "numpy")]
    results = [sim.run(0.5) for sim in sims]
    np.testing.assert_allclose(results[0].state, results[1].state, rtol=0, atol=1e-10)


def test_batched_two_links_with_reads_inside_the_step(rng):
    # delays from 0 to 50 ms: some stages read inside the current step (from the stage state)
    forward = SwitchingDelay(0.0, 0.05, dwell=0.0037, mode="extremes", seed=7, batch=LANES + 1)
    backward = SwitchingDelay(0.0005, 0.03, dwell=0.002, seed=8, batch=LANES + 1)
    scenario = replace(paper_scenarios(rng, batch=LANES + 1), forward=forward, backward=backward)
    _compare(scenario, rng.uniform(1.0, 50.0, size=(30, LANES + 1, 4)), 30)


@pytest.mark.parametrize("dwell", [0.0037, 0.005])
def test_reused_delayed_reads_are_the_same_bits(rng, monkeypatch, dwell):
    # delays longer than the step (3 ms > 2.5 ms): a stage reuses the reads of the stage at the
    # same time; switches inside steps (3.7 ms) and at step ends (5 ms, left limits)
    forward = SwitchingDelay(0.003, 0.05, dwell=dwell, seed=9, batch=LANES + 1)
    scenario = replace(paper_scenarios(rng, batch=LANES + 1), forward=forward)
    assert min(delay_floor(forward), delay_floor(scenario.backward)) > DEFAULT_DT
    gains = rng.uniform(1.0, 50.0, size=(30, LANES + 1, 4))
    _compare(scenario, gains, 30)
    reused = Simulator(scenario).advance(gains)
    real = kernel._advance
    monkeypatch.setattr(kernel, "_advance", lambda *args: real(*args[:-1], False))
    computed = Simulator(scenario).advance(gains)
    np.testing.assert_array_equal(reused.state, computed.state)
    np.testing.assert_array_equal(reused.delayed, computed.delayed)


def test_reads_are_reused_only_when_every_delay_exceeds_the_step():
    delays = np.full((17, 2, 3), 0.002)
    ones = np.ones((2, 3))
    assert delays_exceed(delays, ones, 0.00125)
    for short in (0.00125, 0.0, np.nan):
        delays[5, 1, 2] = short
        assert not delays_exceed(delays, ones, 0.00125)
        assert delays_exceed(delays[:, :, :2], ones[:, :2], 0.00125)


def test_reuse_of_reads_with_one_shape_of_time_and_scales():
    # the delays are shape[s, c] * scale[c, b]: the smallest product decides
    shape = np.full((17, 2, 1), 0.5)
    scale = np.full((2, 40), 0.004)
    assert delays_exceed(shape, scale, 0.00125)  # 0.002 s everywhere
    scale[1, 39] = 0.0025
    assert not delays_exceed(shape, scale, 0.00125)  # 0.00125 s: not longer
    scale[1, 39] = 0.004
    shape[16, 0, 0] = 0.3125
    assert not delays_exceed(shape, scale, 0.00125)
    for bad in (np.nan, -1.0):
        shape[16, 0, 0], scale[0, 3] = 0.5, bad
        assert not delays_exceed(shape, scale, 0.00125)


@dataclass(frozen=True)
class _Unfactored:
    """A profile's samples without its factors: the simulator keeps a column per scenario."""

    profile: FourierDelay

    @property
    def bound(self) -> float:
        return self.profile.bound

    @property
    def floor(self) -> float:
        return self.profile.floor

    def sample(self, t: np.ndarray) -> np.ndarray:
        return self.profile.sample(t)


@pytest.mark.parametrize("batch", [1, LANES + 3])
def test_factored_delays_give_the_same_bits_as_a_column_per_scenario(rng, batch):
    scenario = paper_scenarios(rng, batch=batch)
    columns = replace(scenario, forward=_Unfactored(scenario.forward),
                      backward=_Unfactored(scenario.backward))
    gains = rng.uniform(1.0, 50.0, size=(40, batch, 4))
    factored, full = Simulator(scenario).advance(gains), Simulator(columns).advance(gains)
    for name in ("state", "delayed", "delays"):
        np.testing.assert_array_equal(getattr(factored, name), getattr(full, name))


def test_a_scenario_gives_the_same_bits_alone_and_in_any_lane_of_a_batch():
    """No fused multiply-adds or reassociation: one scenario's run does not depend on the batch
    it runs in (alone, in a full block, in the partial last block)."""
    params = paper_scenarios(0, batch=1).params
    gains = np.array([[1.0, 0.7]])

    def run(batch: int) -> np.ndarray:
        scenario = Scenario(params, FourierDelay(1.0), FourierDelay(0.8),
                            np.repeat(gains, batch, axis=0))
        return Simulator(scenario).run(5.0, np.array([10.0, 10.0, 30.0, 30.0])).state

    alone, batched = run(1)[:, 0], run(LANES + 6)
    for lane in (0, LANES - 1, LANES, LANES + 5):
        np.testing.assert_array_equal(batched[:, lane], alone)
