"""Tests of teleopkit.rl.networks: the actor and the twin critics."""

from __future__ import annotations

import numpy as np
import torch
from test_rl_td3 import ACT, HIGH, LOW, OBS, filled_buffer, make_agent, parameters

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.networks import Actor
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
