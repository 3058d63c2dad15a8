"""Tests of teleopkit.rl.td3: the TD3 agent's updates, reproducibility and configuration."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from teleopkit.certification.certifier import DEFAULT_BOX
from teleopkit.rl.replay import ReplayBuffer
from teleopkit.rl.td3 import TD3, TD3Config

torch.set_num_threads(1)

OBS, ACT = 14, 4
LOW = np.array([DEFAULT_BOX[0][0]] * 2 + [DEFAULT_BOX[1][0]] * 2)
HIGH = np.array([DEFAULT_BOX[0][1]] * 2 + [DEFAULT_BOX[1][1]] * 2)
SMALL = TD3Config(batch_size=32)


def make_agent(layer, seed=0, config=SMALL):
    return TD3(OBS, LOW, HIGH, layer.polytope, config, seed=seed)


def filled_buffer(layer, size=256, seed=0):
    rng = np.random.default_rng(seed)
    buffer = ReplayBuffer(1024, OBS, ACT, seed=seed)
    actions = layer.project_batch(rng.uniform(-10, 160, (size, ACT))).action
    buffer.add(rng.normal(size=(size, OBS)), actions, -rng.random(size),
               rng.normal(size=(size, OBS)), np.zeros(size))
    return buffer


def parameters(module):
    return torch.cat([p.detach().flatten() for p in module.parameters()])


def test_target_update_is_a_convex_combination(layer):
    config = TD3Config(batch_size=32, policy_delay=1, tau=0.1)
    agent = make_agent(layer, config=config)
    buffer = filled_buffer(layer)
    agent.update(buffer.sample(32))  # targets now differ from the online networks
    pairs = [(agent.actor_target, agent.actor), (agent.critic_targets, agent.critics)]
    before = [parameters(target).clone() for target, _ in pairs]
    agent.update(buffer.sample(32))
    for (target, online), old in zip(pairs, before, strict=True):
        new, current = parameters(target), parameters(online)
        np.testing.assert_allclose(new, 0.9 * old + 0.1 * current, rtol=1e-5, atol=1e-7)
        assert not torch.equal(new, old)


@pytest.mark.parametrize("valued", ["applied", "raw"])
def test_critic_target_bootstraps_with_the_discount_to_the_transition_span(layer, valued):
    # an actor that starts stiff and barely damped: outside the set, so the two differ
    config = TD3Config(batch_size=32, discount=0.9, target_noise=0.0, reward_scale=0.5,
                       critic_action=valued, start=(45.0, 45.0, 2.0, 2.0))
    agent = make_agent(layer, config=config)
    batch = filled_buffer(layer).sample(32)
    steps = torch.tensor([1.0, 4.0] * 16)
    terminated = torch.tensor([0.0] * 31 + [1.0])
    spanning = batch._replace(steps=steps, terminated=terminated)
    with torch.no_grad():
        raw = agent.actor_target(batch.next_obs)
        low, high = (torch.as_tensor(x, dtype=torch.float32) for x in (LOW, HIGH))
        # the value of the applied gains, or of the raw ones in the box (the set left to the env)
        projected = agent.projection(raw, batch.next_obs)
        assert not torch.allclose(projected, torch.clamp(raw, low, high))
        next_action = projected if valued == "applied" else torch.clamp(raw, low, high)
        q_next = torch.minimum(*(c(batch.next_obs, next_action) for c in agent.critic_targets))
    expected = 0.5 * batch.reward + 0.9 ** steps * (1 - terminated) * q_next
    torch.testing.assert_close(agent._critic_target(spanning), expected)


def test_actor_and_targets_update_every_policy_delay_steps(layer):
    agent = make_agent(layer)  # policy_delay 2
    buffer = filled_buffer(layer)
    actor, target = parameters(agent.actor), parameters(agent.actor_target)
    first = agent.update(buffer.sample(32))
    assert math.isnan(first["actor_loss"]) and math.isfinite(first["critic_loss"])
    assert torch.equal(parameters(agent.actor), actor)
    assert torch.equal(parameters(agent.actor_target), target)
    second = agent.update(buffer.sample(32))
    assert math.isfinite(second["actor_loss"])
    assert not torch.equal(parameters(agent.actor), actor)
    assert not torch.equal(parameters(agent.actor_target), target)


def test_gradients_are_clipped(layer):
    config = TD3Config(batch_size=32, grad_clip=1e-3, critic_lr=1.0)
    agent = make_agent(layer, config=config)
    buffer = filled_buffer(layer)
    batch = buffer.sample(32)
    before = [parameters(critic) for critic in agent.critics]
    agent.update(batch)
    # Adam's first step moves each weight by lr * sign(g) whatever the norm; clipping shows
    # up in the stored gradients: each critic's, far above the threshold unclipped, is clipped
    # by its own norm to the threshold (a joint clip would leave each below it).
    for critic, old in zip(agent.critics, before, strict=True):
        norm = torch.sqrt(sum(p.grad.pow(2).sum() for p in critic.parameters()))
        assert float(norm) == pytest.approx(1e-3, rel=1e-3)
        assert not torch.equal(parameters(critic), old)


def test_seeded_agents_are_reproducible(layer):
    runs = []
    for seed in (0, 0, 1):
        agent = make_agent(layer, seed=seed)
        buffer = filled_buffer(layer)
        for _ in range(4):
            agent.update(buffer.sample(32))
        runs.append(torch.cat([parameters(agent.actor), parameters(agent.critics)]))
    assert torch.equal(runs[0], runs[1])
    assert not torch.equal(runs[0], runs[2])


def test_state_dict_round_trip_continues_identically(layer):
    buffer_a, buffer_b = filled_buffer(layer), filled_buffer(layer)
    a = make_agent(layer, seed=3)
    for _ in range(3):
        a.update(buffer_a.sample(32))
    b = make_agent(layer, seed=99)
    b.load_state_dict(a.state_dict())
    buffer_b.load_state_dict(buffer_a.state_dict())
    for _ in range(3):
        a.update(buffer_a.sample(32))
        b.update(buffer_b.sample(32))
    assert torch.equal(parameters(a.actor), parameters(b.actor))
    assert torch.equal(parameters(a.critic_targets), parameters(b.critic_targets))


def test_exploration_noise_and_its_decay(layer):
    config = TD3Config()
    assert config.exploration_std_at(0) == 4.0
    assert config.exploration_std_at(10**6) == pytest.approx(4.0 * (1 - 1e-7) ** 10**6)
    assert config.exploration_std_at(10**9) == 0.05
    agent = make_agent(layer)
    obs = np.zeros((2000, OBS))
    clean = agent.act(obs)
    noisy = agent.act(obs, 4.0, np.random.default_rng(0))
    assert np.std(noisy - clean) == pytest.approx(4.0, rel=0.05)
    with pytest.raises(ValueError, match="generator"):
        agent.act(obs, 1.0)


@pytest.mark.parametrize("bad", [{"discount": 1.5}, {"tau": 0.0}, {"batch_size": 0},
                                 {"policy_delay": 0}, {"actor_lr": 0.0},
                                 {"exploration_std_min": 5.0}, {"exploration_decay": 1.0},
                                 {"critic_action": "projected"}])
def test_config_rejects_bad_values(bad):
    with pytest.raises(ValueError):
        TD3Config(**bad)


def test_construction_leaves_the_global_rng_alone(layer):
    state = torch.get_rng_state()
    make_agent(layer)
    assert torch.equal(state, torch.get_rng_state())
