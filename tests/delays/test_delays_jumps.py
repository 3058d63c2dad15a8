"""Tests of teleopkit.delays.jumps: which profiles jump, and their left limits."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.delays import (
    ConstantDelay,
    FourierDelay,
    PiecewiseDelay,
    ScaledDelay,
    SinusoidalDelay,
    SquareWaveDelay,
    StackedDelay,
    SwitchingDelay,
)
from teleopkit.delays.jumps import has_jumps, sample_left

JUMPING = {
    "switching": SwitchingDelay(0.1, 0.9, dwell=0.25, mode="extremes", seed=4, batch=3),
    "square wave": SquareWaveDelay([0.1, 0.2], [0.6, 0.9], [0.25, 0.4], [0.0, 0.05]),
    "piecewise": PiecewiseDelay([[0.0, 0.25, 0.6], [0.1, 0.5, 0.5]],
                                [[0.2, 0.7, 0.4], [0.3, 0.1, 0.8]]),
}


@pytest.mark.parametrize("name", sorted(JUMPING))
def test_left_limits_are_the_values_just_before(name):
    """``sample_left`` is ``sample`` a moment earlier: the old value at a switch, the same
    value between switches."""
    profile = JUMPING[name]
    assert has_jumps(profile)
    t = np.concatenate([np.linspace(0.0, 2.0, 81), [0.25, 0.5, 0.6, 0.65, 1.0]])
    left = profile.sample_left(t)
    np.testing.assert_array_equal(left[1:], profile.sample(t[1:] - 1e-6))
    away = np.abs(t[:, None] - np.asarray(_switches(profile))).min(axis=1) > 1e-6
    np.testing.assert_array_equal(left[away], profile.sample(t[away]))
    assert np.any(left != profile.sample(t))  # some time is a switch


def _switches(profile) -> list[float]:
    """Times at which ``profile`` may switch within [0, 2] s."""
    if isinstance(profile, SwitchingDelay):
        return list(np.arange(0.0, 2.01, profile.dwell))
    if isinstance(profile, SquareWaveDelay):
        return [k * h - p for h, p in zip(profile.half_period, profile.phase, strict=True)
                for k in range(12)]
    return list(profile.times.ravel())


def test_wrappers_jump_as_their_parts_and_continuous_profiles_do_not():
    t = np.array([0.25, 0.3])
    switching = SwitchingDelay(0.1, 0.9, dwell=0.25, mode="extremes", seed=4)
    for continuous in (FourierDelay(1.0), ConstantDelay(0.3), SinusoidalDelay(0.5, 0.2, 1.0)):
        assert not has_jumps(continuous)
        np.testing.assert_array_equal(sample_left(continuous, t), continuous.sample(t))
        assert not has_jumps(ScaledDelay(continuous, 0.5))
    scaled = ScaledDelay(switching, 0.5)
    assert has_jumps(scaled)
    np.testing.assert_array_equal(scaled.sample_left(t), 0.5 * switching.sample_left(t))
    stacked = StackedDelay((FourierDelay(1.0), switching))
    assert has_jumps(stacked)
    np.testing.assert_array_equal(stacked.sample_left(t),
                                  np.concatenate([FourierDelay(1.0).sample(t),
                                                  switching.sample_left(t)], axis=1))


def test_a_part_shared_by_several_scenarios_is_sampled_once_per_call():
    """Stacking one profile object many times gives its columns repeated, from one sample."""
    calls: list[int] = []

    class Counted(SinusoidalDelay):
        def sample(self, t):
            calls.append(1)
            return super().sample(t)

    shared = Counted(0.5, 0.2, 1.0, phase=[0.0, 1.0])
    other = SwitchingDelay(0.1, 0.9, dwell=0.25, seed=4, batch=1)
    stacked = StackedDelay((shared, other, shared, shared), order=(6, 0, 1, 2, 3, 4, 5))
    t = np.linspace(0.0, 2.0, 9)
    calls.clear()
    values = stacked.sample(t)
    alone = np.concatenate([shared.sample(t), other.sample(t), shared.sample(t),
                            shared.sample(t)], axis=1)[:, [6, 0, 1, 2, 3, 4, 5]]
    assert len(calls) == 1 + 3  # once in the stack, three times for the reference
    np.testing.assert_array_equal(values, alone)
    left = np.concatenate([shared.sample(t), sample_left(other, t), shared.sample(t),
                           shared.sample(t)], axis=1)[:, [6, 0, 1, 2, 3, 4, 5]]
    np.testing.assert_array_equal(stacked.sample_left(t), left)
    with pytest.raises(ValueError, match="permutation"):
        StackedDelay((shared, other), order=(0, 1))
