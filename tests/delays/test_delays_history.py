"""Tests of teleopkit.delays.history: a sender's samples read back at ``t - T(t)``."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.delays import SwitchingDelay
from teleopkit.delays.history import ChannelHistory

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
