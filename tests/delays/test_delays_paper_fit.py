"""Tests of teleopkit.delays.paper_fit: the paper's Fourier fit of the delay profile."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.delays import PAPER_DELAY_MAX, FourierDelay
from teleopkit.delays.paper_fit import PAPER_C0, PAPER_COS, PAPER_F0, PAPER_SIN, paper_shape


def test_paper_profile_range_and_bound():
    t = np.linspace(0, 40, 40001)
    y = FourierDelay(1.0).sample(t)[:, 0]
    assert 0.90 < y.min() < 0.905 and 0.9995 < y.max() <= 1.0  # the fit, scaled to T* = 1 s
    assert 1.0 < PAPER_DELAY_MAX < 1.001
    scaled = FourierDelay(np.array([0.5, 1.0])).sample(t)
    np.testing.assert_allclose(scaled[:, 0], 0.5 * scaled[:, 1])


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
