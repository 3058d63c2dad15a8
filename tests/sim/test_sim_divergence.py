"""A run that diverges says so: when, and how (a warning in Python, a flag per scenario)."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

import teleopkit as tk
from teleopkit.model.params import InitialState, Wall, paper_setup
from teleopkit.setup import Setup
from teleopkit.sim import simulator as simulator_module
from teleopkit.sim.divergence import Divergence, DivergenceWarning, position_magnitude
from teleopkit.sim.simulator import simulate_trajectory

UNSATURATED = Setup.from_params(replace(paper_setup(), torque_limit=math.inf))
"""The paper's teleoperator without torque saturation: K_r = 100, B_r = 0 behind 1 s delays
grows until a position passes 20 rad (at 12.43 s)."""

RUNAWAY = {"gains": (100.0, 0.0), "duration": 15.0, "delay": "constant:1",
           "setup": UNSATURATED}


def _first(t: np.ndarray, gone: np.ndarray) -> float:
    return float(t[np.argmax(gone)]) if gone.any() else math.nan


def test_a_runaway_run_warns_with_the_time_a_position_passed_the_radius():
    with pytest.warns(DivergenceWarning, match="a position passed 20 rad") as caught:
        trajectory = simulate_trajectory(**RUNAWAY)
    t, state = trajectory.t, trajectory.state[:, 0]
    expected = _first(t, position_magnitude(state) > 20.0)
    assert 1.0 < expected < 15.0 and np.isfinite(state[t <= expected]).all()
    assert str(caught[0].message) == f"the run diverged at t = {expected:g} s: a position passed " \
                                     "20 rad"
    assert trajectory.diverged_at() == pytest.approx([expected])
    # Past 20 rad the growth depends on rounding (on some CPUs a step overflows): a larger
    # radius is passed no sooner, if at all.
    farther = trajectory.diverged_at(Divergence(radius=1e6))
    assert np.isnan(farther).all() or (farther >= expected).all()


def test_the_table_of_simulate_warns_too_and_keeps_the_run():
    with pytest.warns(DivergenceWarning, match="the run diverged at t = "):
        table = tk.simulate(**RUNAWAY)
    positions = table.filter(regex=r"^(ql|qr|theta)_\d$").to_numpy()
    assert len(table) == 1501 and np.nanmax(np.abs(positions)) > 20.0  # every row, kept


def test_a_stable_run_neither_warns_nor_is_flagged():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trajectory = simulate_trajectory((10.0, 30.0), duration=15.0, delay="constant:1",
                                         setup=UNSATURATED)
    assert np.isnan(trajectory.diverged_at()).all()


def test_a_state_that_overflows_is_said_to_stop_being_finite(monkeypatch):
    """The trial's wall, too stiff for the step, with the simulator's check switched off."""
    walled = replace(paper_setup(), environment=Wall((0.5, math.inf), 1e9, 5.0),
                     initial=InitialState((0.8, 0.0), (0.45, 0.0), (0.55, 0.0)))
    monkeypatch.setattr(simulator_module, "check_step", lambda *args: None)
    with pytest.warns(DivergenceWarning, match="its state stopped being finite") as caught:
        trajectory = simulate_trajectory((10.0, 30.0), duration=2.0, delay="constant:0.2",
                                         setup=Setup.from_params(walled))
    state = trajectory.state[:, 0]
    expected = _first(trajectory.t, ~np.isfinite(state).all(axis=1))
    assert f"at t = {expected:g} s" in str(caught[0].message)
    assert trajectory.diverged_at() == pytest.approx([expected])


def test_the_onset_agrees_with_the_campaign_verdict(rng):
    """A run has an onset exactly when the verdict's first two tests call it diverged."""
    state = rng.normal(scale=2.0, size=(40, 64, 24))
    state[rng.integers(40, size=6), rng.integers(64, size=6), rng.integers(24, size=6)] = np.nan
    state[rng.integers(40, size=6), rng.integers(64, size=6), rng.integers(24, size=6)] = 25.0
    t = np.arange(40) * 0.01
    criterion = Divergence(min_duration=1e9)  # no growth test
    onset = criterion.onset(t, state)
    verdict = criterion.assess(position_magnitude(state[1:]),
                               np.isfinite(state).all(axis=(0, 2)), 0.39)
    first_gone = (position_magnitude(state[:1]) > criterion.radius)[0]
    assert np.array_equal(~np.isnan(onset), verdict["diverged"] | first_gone)
    assert 0 < np.isnan(onset).sum() < 64
