"""Operator reference motions against their definitions."""

from __future__ import annotations

import numpy as np

from teleopkit.sim.motions import SineMotion


def test_sums_of_sines_are_their_definition_with_still_and_undamped_components():
    rng = np.random.default_rng(3)
    shape = (5, 3, 2)  # scenarios, components, joints
    amplitudes = rng.uniform(-2, 2, shape)
    amplitudes[1] = 0.0  # a still operator
    amplitudes[2, 1:] = 0.0  # one component only (a mix pads the others)
    decays = rng.uniform(0, 0.3, shape)
    decays[3] = 0.0  # a motion that never dies out
    frequencies, phases = rng.uniform(0, 10, shape), rng.uniform(-np.pi, np.pi, shape)
    motion = SineMotion(amplitudes, frequencies, phases, decays)
    times = np.linspace(0.0, 40.0, 257)
    got = motion.sample(times)
    assert got.shape == (257, 5, 2)
    t = times[:, None, None, None]
    expected = (amplitudes * np.sin(frequencies * t + phases) * np.exp(-decays * t)).sum(axis=2)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14)
    assert np.all(got[:, 1] == 0.0)
    shared = SineMotion(amplitudes[:1], frequencies[:1], phases[:1], decays[:1])
    np.testing.assert_array_equal(shared.sample(times), got[:, :1])
