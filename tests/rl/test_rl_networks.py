"""Tests of teleopkit.rl.networks: the actor and the twin critics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from test_rl_td3 import ACT, HIGH, LOW, OBS, SMALL, filled_buffer, make_agent, parameters

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.networks import Actor, Critic
from teleopkit.rl.td3 import TD3Config
from teleopkit.safety.factory import layer_for


def test_actor_shapes_and_layer_sizes():
    actor = Actor(OBS, LOW, HIGH, torch.Generator().manual_seed(0))
    out = actor(torch.randn(7, OBS))
    assert out.shape == (7, ACT)
    linears = [m for m in actor.modules() if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(14, 128), (128, 64), (64, 4)]


def test_actor_output_starts_at_the_box_centre_and_covers_the_box():
    actor = Actor(OBS, LOW, HIGH, torch.Generator().manual_seed(0))
    obs = torch.randn(256, OBS)
    start = actor(obs).detach().numpy()
    np.testing.assert_allclose(start, np.broadcast_to((LOW + HIGH) / 2, start.shape), rtol=0.05)
    with torch.no_grad():
        actor.head.weight.zero_()
        actor.head.bias.fill_(-40.0)
        low = actor(obs).numpy()
        actor.head.bias.fill_(5.0)
        high = actor(obs).numpy()
    assert np.all(low >= LOW) and np.allclose(low, LOW, atol=1e-6)
    assert np.all(high > HIGH)  # beyond the upper corner: every gain in the box is reachable


def test_tanh_actor_stays_in_the_box_and_starts_where_asked():
    start = np.array([4.0, 7.0, 10.0, 120.0])
    actor = Actor(OBS, LOW, HIGH, torch.Generator().manual_seed(0), start=start, output="tanh")
    obs = torch.randn(512, OBS, generator=torch.Generator().manual_seed(1)) * 1e4
    gains = actor(obs).detach().numpy()  # saturated: never beyond the box
    assert np.all(gains >= LOW) and np.all(gains <= HIGH)
    with torch.no_grad():
        actor.head.weight.zero_()
        saved = actor.head.bias.clone()
        for bias, corner in ((-40.0, LOW), (40.0, HIGH)):  # both corners are reached
            actor.head.bias.fill_(bias)
            np.testing.assert_allclose(actor(obs).numpy(), np.broadcast_to(corner, gains.shape))
        actor.head.bias.copy_(saved)
        actor.head.weight.zero_()  # z is the bias alone: the start's offset plus the initial draw
        fresh = Actor(OBS, LOW, HIGH, torch.Generator().manual_seed(0), output="tanh")
        actor.head.bias.sub_(fresh.head.bias)
    np.testing.assert_allclose(actor(obs).detach().numpy()[0], start, rtol=1e-5)


def test_tanh_actor_refuses_a_start_on_the_box_edge_and_keeps_fixed_gains():
    with pytest.raises(ValueError, match="inside the box"):
        Actor(OBS, LOW, HIGH, torch.Generator(), start=HIGH.copy(), output="tanh")
    low, high = LOW.copy(), HIGH.copy()
    high[0] = low[0]  # a stiffness with a single value
    actor = Actor(OBS, low, high, torch.Generator().manual_seed(0), output="tanh")
    assert torch.all(actor(torch.randn(64, OBS) * 100)[:, 0] == float(low[0]))
    with pytest.raises(ValueError, match="output must be one of softplus, tanh, got 'relu'"):
        Actor(OBS, LOW, HIGH, torch.Generator(), output="relu")
    with pytest.raises(ValueError, match="output_map must be one of"):
        TD3Config(output_map="sigmoid")


def test_joined_critic_takes_the_action_at_its_input(layer):
    critic = Critic(OBS, LOW, HIGH, torch.Generator().manual_seed(0), hidden_action=())
    shapes = [(m.in_features, m.out_features) for m in critic.modules()
              if isinstance(m, torch.nn.Linear)]
    assert shapes == [(OBS + ACT, 128), (128, 64), (64, 60), (60, 36), (36, 1)]
    obs = torch.randn(8, OBS)
    action = torch.as_tensor(np.tile((LOW + HIGH) / 2, (8, 1)), dtype=torch.float32)
    action.requires_grad_(True)
    critic(obs, action).sum().backward()
    assert action.grad is not None and torch.all(action.grad.abs().sum(-1) > 0)
    agent = make_agent(layer, config=dataclasses.replace(SMALL, hidden_action=()))
    agent.update(filled_buffer(layer).sample(32))  # the learner runs with it
    assert agent.updates == 1


def test_critic_sizes():
    agent = make_agent(layer_for(default_certificate()))
    critic = agent.critics[0]
    shapes = [(m.in_features, m.out_features) for m in critic.modules()
              if isinstance(m, torch.nn.Linear)]
    assert shapes == [(14, 128), (128, 64), (4, 64), (128, 60), (60, 36), (36, 1)]
    q = critic(torch.randn(5, OBS), torch.as_tensor(np.tile(LOW, (5, 1)), dtype=torch.float32))
    assert q.shape == (5,)


def test_twin_critics_are_independent(layer):
    agent = make_agent(layer)
    first, second = agent.critics
    assert not torch.equal(parameters(first), parameters(second))
    ids = {p.data_ptr() for p in first.parameters()}
    assert ids.isdisjoint(p.data_ptr() for p in second.parameters())
    batch = filled_buffer(layer).sample(32)
    first(batch.obs, batch.action).pow(2).mean().backward()
    assert all(p.grad is not None for p in first.parameters())
    assert all(p.grad is None for p in second.parameters())
    assert agent.critic_optimizers[0] is not agent.critic_optimizers[1]
