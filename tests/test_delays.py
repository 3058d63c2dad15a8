"""Delay profiles and delay channels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleopkit.delays import (
    PAPER_DELAY_MAX,
    ConstantDelay,
    FourierDelay,
    PiecewiseDelay,
    ScaledDelay,
    SinusoidalDelay,
    SquareWaveDelay,
    StackedDelay,
    SwitchingDelay,
    TraceDelay,
    parse_delay,
)
from teleopkit.delays.history import ChannelHistory
from teleopkit.delays.jumps import has_jumps, sample_left
from teleopkit.delays.paper_fit import PAPER_C0, PAPER_COS, PAPER_F0, PAPER_SIN, paper_shape

DT = 0.01


def _fill(channel: ChannelHistory, signal, derivative, steps: int) -> None:
    for k in range(1, steps + 1):
        channel.record(signal(k * DT), derivative(k * DT))


@pytest.mark.parametrize(("signal", "derivative"), [
    (lambda t: np.array([[0.3 + 2.0 * t, -1.0 * t]]), lambda t: np.array([[2.0, -1.0]])),
    (lambda t: np.array([[t**3 - t, 0.5 * t**2]]), lambda t: np.array([[3 * t**2 - 1, t]])),
])
def test_channel_exact_on_cubics_across_switching_delays(signal, derivative):
    channel = ChannelHistory(signal(0.0), DT, bound=0.5)
    _fill(channel, signal, derivative, 100)
    now = 100 * DT
    profile = SwitchingDelay(0.0, 0.5, dwell=0.013, seed=2)
    for offset in (0.0, 0.3, 0.5):
        t = now + offset * DT
        latest = (signal(t), derivative(t))
        for delay in profile.sample(np.linspace(0, 1, 40))[:, 0]:
            got = channel.read(offset, np.array([delay]), latest)
            np.testing.assert_allclose(got, signal(t - delay), atol=1e-12)


def test_channel_holds_the_initial_value_before_the_first_sample():
    channel = ChannelHistory(np.array([[1.5]]), DT, bound=1.0)
    _fill(channel, lambda t: np.array([[1.5 + t]]), lambda t: np.array([[1.0]]), 10)
    got = channel.read(0.0, np.array([0.9]), (np.array([[1.6]]), np.array([[1.0]])))
    np.testing.assert_allclose(got, [[1.5]])


def test_channel_zero_delay_returns_the_current_stage():
    channel = ChannelHistory(np.zeros((2, 1)), DT, bound=0.1)
    latest = (np.array([[0.7], [-0.2]]), np.array([[3.0], [1.0]]))
    got = channel.read(0.5, np.zeros(2), latest)
    np.testing.assert_array_equal(got, latest[0])


def test_paper_profile_range_and_bound():
    t = np.linspace(0, 40, 40001)
    y = FourierDelay(1.0).sample(t)[:, 0]
    assert 0.90 < y.min() < 0.905 and 0.9995 < y.max() <= 1.0  # the fit, scaled to T* = 1 s
    assert 1.0 < PAPER_DELAY_MAX < 1.001
    scaled = FourierDelay(np.array([0.5, 1.0])).sample(t)
    np.testing.assert_allclose(scaled[:, 0], 0.5 * scaled[:, 1])


def test_profiles_stay_within_their_bounds():
    t = np.linspace(0, 20, 5001)
    profiles = [ConstantDelay(0.3), SinusoidalDelay(0.5, 0.5, 2.0, np.array([0.0, 1.0])),
                SwitchingDelay(0.1, 0.9, 0.01, "extremes", seed=1, batch=3),
                SwitchingDelay(0.1, 0.9, 0.05, seed=1, batch=3)]
    for profile in profiles:
        values = profile.sample(t)
        assert values.min() >= 0 and values.max() <= profile.bound


def test_switching_is_reproducible_bounded_and_seeded():
    profile = SwitchingDelay(0.2, 0.8, dwell=0.01, mode="extremes", seed=5, batch=4)
    t = np.linspace(0, 5, 1001)
    values = profile.sample(t)
    np.testing.assert_array_equal(values, profile.sample(t))
    np.testing.assert_array_equal(values[::-1], profile.sample(t[::-1]))
    assert set(np.unique(values)) == {0.2, 0.8}
    assert not np.array_equal(values, SwitchingDelay(0.2, 0.8, 0.01, "extremes", 6, 4).sample(t))
    uniform = SwitchingDelay(0.0, 1.0, dwell=0.01, seed=1).sample(np.arange(20000) * 0.01)
    assert abs(uniform.mean() - 0.5) < 0.01 and abs(uniform.std() - math.sqrt(1 / 12)) < 0.01


def test_profile_above_its_declared_bound_is_refused():
    with pytest.raises(ValueError, match="above its declared bound"):
        FourierDelay(1.0, bound=0.95).sample(np.linspace(0, 5, 100))
    with pytest.raises(ValueError, match="above its declared bound"):
        TraceDelay(np.array([0.0, 1.0]), np.array([0.2, 0.6]), bound=0.5).sample(np.array([0.9]))


def test_trace_from_csv(tmp_path):
    path = tmp_path / "trace.csv"
    path.write_text("t,delay\n0,0.1\n1,0.3\n2,0.2\n")
    trace = TraceDelay.from_csv(path)
    np.testing.assert_allclose(trace.sample(np.array([0.5, 1.5, 9.0]))[:, 0], [0.2, 0.25, 0.2])
    assert trace.bound == pytest.approx(0.3)
    forward, backward = parse_delay(f"csv:{path}")
    assert forward is backward


@pytest.mark.parametrize(("content", "message"), [
    ("t,delay\n0,0.1\n", "at least 2 rows"),
    ("t,delay\n0,0.1\n0,0.2\n", "strictly increasing"),
    ("t,delay\n0,0.1\n1,-0.2\n", "negative"),
    ("t,delay\n0,abc\n1,0.2\n", "non-numeric"),
    ("t\n0\n1\n", "no delay column"),
    ("t,delay\n0,nan\n1,0.2\n", "non-finite"),
])
def test_bad_traces_are_refused(tmp_path, content, message):
    path = tmp_path / "trace.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        TraceDelay.from_csv(path)


def test_missing_trace_file_is_refused(tmp_path):
    with pytest.raises(ValueError, match="cannot read delay trace"):
        TraceDelay.from_csv(tmp_path / "absent.csv")


@pytest.mark.parametrize("spec", ["", "paperx", "constant", "constant:a", "sine:1:2",
                                  "constant:-1", "sine:0.1:0.5:1", "csv:"])
def test_bad_delay_specs_are_refused(spec):
    with pytest.raises(ValueError):
        parse_delay(spec)


def test_delay_specs():
    forward, backward = parse_delay("constant:0.25")
    assert forward.bound == backward.bound == 0.25
    forward, backward = parse_delay("switching:0:1:0.01", np.random.default_rng(0))
    assert forward.seed != backward.seed
    forward, _ = parse_delay("paper", np.random.default_rng(0))
    assert 0.5 <= float(forward.scale[0]) <= 1.0


@pytest.mark.parametrize("size", [1, 255, 256, 257, 5000])
def test_fourier_delay_is_the_direct_sum_of_its_harmonics(size):
    t = np.random.default_rng(size).uniform(-3.0, 200.0, size)
    angles = 2.0 * np.pi * PAPER_F0 * np.outer(t, np.arange(1, PAPER_SIN.size + 1))
    direct = PAPER_C0 + np.sin(angles) @ PAPER_SIN + np.cos(angles) @ PAPER_COS
    sampled = FourierDelay(np.array([1.0, 0.5])).sample(t)
    np.testing.assert_allclose(sampled[:, 0], direct / PAPER_DELAY_MAX, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sampled[:, 1], 0.5 * direct / PAPER_DELAY_MAX, rtol=0, atol=1e-14)


def test_the_remembered_paper_shape_is_never_stale():
    t = np.linspace(0.0, 9.0, 700)
    first = paper_shape(t)
    first[:] = 0.0  # the caller's copy: the remembered one is untouched
    again = paper_shape(t)
    assert np.all(again > 0.9)
    t[3] += 1.0  # the same array with other times
    moved = paper_shape(t)
    np.testing.assert_array_equal(np.delete(moved, 3), np.delete(again, 3))
    assert moved[3] == paper_shape(t[3:4])[0] != again[3]


@pytest.mark.parametrize("profile", [FourierDelay(np.array([0.5, 0.75, 1.0])),
                                     FourierDelay(0.8), ConstantDelay(np.array([0.0, 0.3])),
                                     ConstantDelay(0.25)])
def test_factors_multiply_to_the_samples_bit_for_bit(profile):
    t = np.linspace(0.0, 40.0, 4001)
    shape, scale = profile.factors(t)
    assert shape.shape == t.shape and scale.ndim == 1
    np.testing.assert_array_equal(np.multiply.outer(shape, scale), profile.sample(t))


def test_factors_are_checked_against_the_bound():
    with pytest.raises(ValueError, match="above its declared bound"):
        FourierDelay(1.0, bound=0.95).factors(np.linspace(0.0, 40.0, 401))


def test_factors_are_fresh_arrays():
    profile = FourierDelay(np.array([0.5, 0.75]))
    profile.factors(np.zeros(3))[1][:] = 9.0
    np.testing.assert_array_equal(profile.scale, [0.5, 0.75])


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
