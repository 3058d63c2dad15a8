"""Tests of teleopkit.rl.policy: the numpy gain policy and its files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_rl_td3 import ACT, HIGH, LOW, OBS, SMALL, filled_buffer, make_agent

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


def test_tanh_policy_file_round_trips_and_keeps_its_map(layer, tmp_path):
    agent = make_agent(layer, config=dataclasses.replace(SMALL, output_map="tanh"))
    agent.set_normalizer(np.zeros(OBS), np.full(OBS, 0.01))  # large inputs: outputs saturate
    obs = np.random.default_rng(2).normal(size=(256, OBS))
    policy = agent.policy()
    assert policy.output == "tanh"
    np.testing.assert_allclose(policy(obs), agent.act(obs), rtol=1e-5, atol=1e-4)
    gains = policy(obs)
    assert np.all(gains >= LOW) and np.all(gains <= HIGH)
    policy.save(tmp_path / "tanh.npz")
    loaded = GainPolicy.load(tmp_path / "tanh.npz")
    assert loaded.output == "tanh" and loaded.fingerprint == policy.fingerprint
    np.testing.assert_allclose(loaded(obs), gains, rtol=1e-6)
    as_softplus = GainPolicy(policy.weights, policy.obs_mean, policy.obs_std, policy.low,
                             policy.span)
    assert as_softplus.fingerprint != policy.fingerprint  # the map is part of what it computes
    assert not np.allclose(as_softplus(obs), gains)


def test_a_file_without_a_map_is_the_papers_softplus(tmp_path):
    policy = GainPolicy.pretrained("covered")
    policy.save(tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz") as data:  # a file written before the map was recorded
        np.savez(tmp_path / "old.npz", **{k: data[k] for k in data.files if k != "output"})
    old = GainPolicy.load(tmp_path / "old.npz")
    assert old.output == "softplus" and old.fingerprint == policy.fingerprint
    obs = np.random.default_rng(3).normal(size=(16, policy.obs_mean.size))
    np.testing.assert_allclose(old(obs), policy(obs))
    with pytest.raises(ValueError, match="output must be one of"):
        GainPolicy(policy.weights, policy.obs_mean, policy.obs_std, policy.low, policy.span,
                   output="linear")
