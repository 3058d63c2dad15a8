"""Tests of teleopkit.rl.policy: the numpy gain policy and its files."""

from __future__ import annotations

import numpy as np
import pytest
from test_rl_td3 import ACT, OBS, filled_buffer, make_agent

from teleopkit.rl.policy import GainPolicy


def test_gain_policy_matches_the_actor_and_round_trips(layer, tmp_path):
    agent = make_agent(layer)
    agent.set_normalizer(np.linspace(-1, 1, OBS), np.linspace(0.1, 2, OBS))
    buffer = filled_buffer(layer)
    for _ in range(6):
        agent.update(buffer.sample(32))
    policy = agent.policy({"note": "test"})
    obs = np.random.default_rng(1).normal(size=(64, OBS))
    np.testing.assert_allclose(policy(obs), agent.act(obs), rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(policy(obs[0]), policy(obs[:1])[0])
    path = tmp_path / "policy.npz"
    policy.save(path)
    loaded = GainPolicy.load(path)
    np.testing.assert_allclose(loaded(obs), policy(obs), rtol=1e-6)
    assert loaded.metadata == {"note": "test"} and loaded.action_dim == ACT
    assert path.stat().st_size < 100_000


def test_gain_policy_rejects_other_files(tmp_path):
    path = tmp_path / "bad.npz"
    path.write_text("not a policy")
    with pytest.raises(ValueError, match="not a teleopkit policy"):
        GainPolicy.load(path)
    np.savez(tmp_path / "other.npz", x=np.zeros(2))
    with pytest.raises(ValueError, match="not a teleopkit policy"):
        GainPolicy.load(tmp_path / "other.npz")
