"""The simulator's bookkeeping: inputs sampled ahead, records filled in place."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from teleopkit import (
    ConstantDelay,
    FourierDelay,
    Scenario,
    Simulator,
    SwitchingDelay,
    paper_scenarios,
)
from teleopkit.delays.profiles import check_delays
from teleopkit.sim.tableau import ROWS_PER_STEP

GAINS = np.array([12.0, 9.0, 35.0, 28.0])


@pytest.mark.parametrize("backend", ["compiled", "numpy"])
def test_period_by_period_equals_a_run(backend):
    scenario = paper_scenarios(3, batch=2)
    run = Simulator(scenario, backend=backend).run(0.3, GAINS)
    sim = Simulator(scenario, backend=backend)
    steps = [sim.advance(GAINS) for _ in range(30)]
    np.testing.assert_array_equal(run.state[1:], np.concatenate([s.state for s in steps]))
    np.testing.assert_array_equal(run.delayed[1:], np.concatenate([s.delayed for s in steps]))
    np.testing.assert_array_equal(run.delays[1:], np.concatenate([s.delays for s in steps]))
    np.testing.assert_array_equal(run.t[1:], np.concatenate([s.t for s in steps]))


def test_a_new_scenario_is_sampled_afresh():
    first, second = paper_scenarios(0, batch=1), paper_scenarios(1, batch=1)
    sim = Simulator(first)
    sim.advance(GAINS)  # samples the first scenario's inputs ahead
    sim.scenario = second
    sim.reset()
    np.testing.assert_array_equal(sim.advance(GAINS).state, Simulator(second).advance(GAINS).state)


@dataclass(frozen=True)
class _Ending:
    """A delay of 0.1 s that cannot be sampled after 0.2 s."""

    bound: float = 0.1

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(t)
        if t.max() > 0.2 + 1e-12:
            raise ValueError("_Ending has no delays after 0.2 s")
        return check_delays("_Ending", np.full((t.size, 1), 0.1), self.bound)


def test_a_profile_that_cannot_be_sampled_ahead_runs_to_its_end():
    scenario = replace(paper_scenarios(0, batch=1), forward=_Ending())
    sim = Simulator(scenario)
    sim.advance(np.broadcast_to(GAINS, (20, 1, 4)))
    assert sim.time == pytest.approx(0.2)
    with pytest.raises(ValueError, match=r"after 0\.2 s"):
        sim.advance(GAINS)


def test_constant_gains_are_recorded_without_a_copy_per_period():
    scenario = replace(paper_scenarios(0, batch=3), forward=ConstantDelay(0.05),
                       backward=ConstantDelay(0.05))
    run = Simulator(scenario).run(0.5, GAINS)
    assert run.gains.shape == (51, 3, 4)
    np.testing.assert_array_equal(run.gains, np.broadcast_to(GAINS, (51, 3, 4)))
    assert not run.gains.flags.writeable
    schedule = np.broadcast_to(GAINS, (50, 3, 4)).copy()
    assert Simulator(scenario).run(0.5, schedule).gains.flags.writeable


@pytest.mark.parametrize("factored", [True, False])
def test_a_run_calls_the_kernel_in_bounded_pieces_with_the_same_result(monkeypatch, factored):
    from teleopkit.sim import simulator

    scenario = paper_scenarios(4, batch=3)
    columns = 1  # the paper's profiles have factors: one column of delays for the batch
    if not factored:
        scenario = replace(scenario, forward=SwitchingDelay(0.1, 0.5, dwell=0.05, seed=1,
                                                            batch=3))
        columns = scenario.batch
    whole = Simulator(scenario).run(0.25, GAINS, chunk=0.25)
    sim = Simulator(scenario)
    # three periods' worth of delay values per call: 25 periods in calls of 3, 3, ..., 1
    monkeypatch.setattr(simulator, "CALL_VALUES", 3 * ROWS_PER_STEP * sim.substeps * columns)
    calls = []
    integrate = sim._integrate
    monkeypatch.setattr(sim, "_integrate", lambda g, out: (calls.append(g.shape[0]),
                                                           integrate(g, out)))
    pieces = sim.run(0.25, GAINS)
    assert calls == [3] * 8 + [1]
    np.testing.assert_array_equal(pieces.state, whole.state)
    np.testing.assert_array_equal(pieces.delayed, whole.delayed)
    np.testing.assert_array_equal(pieces.delays, whole.delays)


@pytest.mark.parametrize("chunk", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_chunk_is_refused(chunk):
    with pytest.raises(ValueError, match="chunk must be a positive number of seconds"):
        Simulator(paper_scenarios(0, batch=1)).run(0.1, GAINS, chunk=chunk)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, -1e-9])
def test_gains_that_are_not_finite_and_non_negative_are_refused(bad):
    simulator = Simulator(paper_scenarios(0, batch=3))
    gains = np.full((2, 3, 4), 10.0)
    gains[1, 2, 3] = bad
    with pytest.raises(ValueError, match="finite and non-negative"):
        simulator.advance(gains)
    assert simulator.time == 0.0  # nothing was simulated
    simulator.advance(np.zeros(4))  # zero gains are admissible


@pytest.mark.parametrize("profile", [FourierDelay(np.array([0.5, 0.6, 0.7])),
                                     SwitchingDelay(0.1, 0.5, dwell=0.05, seed=1, batch=3)])
def test_a_delay_profile_of_another_batch_is_refused(profile):
    with pytest.raises(ValueError, match="forward delay profile has 3 scenarios, the reference "
                                         "gains 5"):
        Scenario(paper_scenarios(0, 1).params, profile, FourierDelay(1.0), np.ones((5, 2)))
    Scenario(paper_scenarios(0, 1).params, profile, FourierDelay(1.0), np.ones((3, 2)))
