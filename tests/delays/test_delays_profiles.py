"""Tests of teleopkit.delays.profiles: delay profiles, their bounds, factors and traces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from teleopkit.delays import (
    ConstantDelay,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
    parse_delay,
)


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
