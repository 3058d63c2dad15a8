"""Tests of teleopkit.rl.replay: the replay buffer."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from teleopkit.rl.replay import ReplayBuffer


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
