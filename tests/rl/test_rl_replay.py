"""Tests of teleopkit.rl.replay: the replay buffer."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from teleopkit.rl.replay import NStepWindow, ReplayBuffer


def test_replay_buffer_wraps_and_samples_reproducibly():
    buffer = ReplayBuffer(5, 2, 1, seed=7)
    for k in range(3):
        rows = np.arange(3) + 3 * k
        buffer.add(np.column_stack([rows, rows]), rows[:, None], rows, rows[:, None] * [1, 1],
                   np.zeros(3))
    assert len(buffer) == 5 and buffer.position == 4
    assert sorted(buffer.reward.tolist()) == [4, 5, 6, 7, 8]
    other = ReplayBuffer(5, 2, 1, seed=0)
    other.load_state_dict(buffer.state_dict())
    a, b = buffer.sample(64), other.sample(64)
    assert all(torch.equal(x, y) for x, y in zip(a, b, strict=True))
    assert set(a.reward.tolist()) <= {4.0, 5.0, 6.0, 7.0, 8.0}


def test_empty_buffer_cannot_be_sampled():
    with pytest.raises(ValueError, match="empty"):
        ReplayBuffer(4, 2, 1).sample(1)


def brute_force(rewards: np.ndarray, n: int, discount: float) -> tuple[np.ndarray, np.ndarray]:
    """n-step reward sums and spans of every step of an episode, from their definition."""
    length = len(rewards)
    spans = np.array([min(n, length - t) for t in range(length)])
    sums = np.array([sum(discount ** i * rewards[t + i] for i in range(spans[t]))
                     for t in range(length)])
    return sums, spans


@pytest.mark.parametrize("n", [1, 3, 7])
@pytest.mark.parametrize("failed", [False, True])
def test_n_step_window_releases_every_step_once_with_its_discounted_sum(n, failed):
    rng = np.random.default_rng(n)
    length, batch, discount = 5, 2, 0.9
    obs = rng.normal(size=(length + 1, batch, 3))
    rewards = rng.normal(size=(length, batch))
    window, released = NStepWindow(n, discount), []
    for t in range(length):
        last = t == length - 1
        terminated = np.array([failed and last, False])
        released += window.push(obs[t], np.full((batch, 1), t), rewards[t], obs[t + 1],
                                terminated, last)
    assert [int(action[0, 0]) for _, action, *_ in released] == list(range(length))
    for b in range(batch):
        sums, spans = brute_force(rewards[:, b], n, discount)
        np.testing.assert_allclose([r[2][b] for r in released], sums, rtol=1e-12)
        np.testing.assert_array_equal([r[5][b] for r in released], spans)
        for t, (first, _, _, after, terminated, _) in enumerate(released):
            np.testing.assert_array_equal(first[b], obs[t, b])
            np.testing.assert_array_equal(after[b], obs[t + spans[t], b])  # s_{t+k}
            # only the transitions that reach the failure end without bootstrapping
            assert terminated[b] == (failed and b == 0 and t + spans[t] == length)


def test_n_step_window_refuses_no_steps():
    with pytest.raises(ValueError, match="n >= 1"):
        NStepWindow(0, 0.99)
