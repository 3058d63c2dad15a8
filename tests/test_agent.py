"""TD3 agent: networks, projection, replay buffer, updates, reproducibility, numpy policy."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from teleopkit.certification.certifier import DEFAULT_BOX, default_certificate
from teleopkit.rl.networks import Actor
from teleopkit.rl.policy import GainPolicy
from teleopkit.rl.replay import ReplayBuffer
from teleopkit.rl.td3 import TD3, TD3Config
from teleopkit.rl.torch_projection import TorchProjection
from teleopkit.safety.factory import layer_for

torch.set_num_threads(1)

OBS, ACT = 14, 4
LOW = np.array([DEFAULT_BOX[0][0]] * 2 + [DEFAULT_BOX[1][0]] * 2)
HIGH = np.array([DEFAULT_BOX[0][1]] * 2 + [DEFAULT_BOX[1][1]] * 2)
SMALL = TD3Config(batch_size=32)


@pytest.fixture(scope="module")
def layer():
    return layer_for(default_certificate())


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


# --- networks ---------------------------------------------------------------------------------

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


# --- projection -------------------------------------------------------------------------------

def test_torch_projection_matches_the_safety_layer(layer):
    projection = TorchProjection(layer.polytope)
    rng = np.random.default_rng(3)
    raw = np.concatenate([rng.uniform(-100, 300, (4000, ACT)),
                          layer.polytope.vertices() + rng.normal(0, 1e-3, (16, ACT)),
                          rng.uniform(1e3, 1e6, (50, ACT)) * rng.choice([-1, 1], (50, ACT))])
    expected = layer.project_batch(raw).action
    got = projection(torch.as_tensor(raw)).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-9)
    single = projection(torch.as_tensor(raw, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(single, expected, rtol=1e-5, atol=1e-3)


def test_projection_gradient_is_identity_inside_and_tangent_on_an_edge(layer):
    projection = TorchProjection(layer.polytope)
    inside = torch.tensor([[10.0, 10.0, 60.0, 60.0]], dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(projection, inside)[0, :, 0, :]
    np.testing.assert_allclose(jac.numpy(), np.eye(ACT))
    # joint 1 beyond the closed-form edge B = 2.5 K (+ slack), joint 2 inside
    point = torch.tensor([[40.0, 10.0, 60.0, 60.0]], dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(projection, point)[0, :, 0, :].numpy()
    step = 1e-6
    numeric = np.column_stack([
        (layer.project(point[0].numpy() + step * e).action
         - layer.project(point[0].numpy() - step * e).action) / (2 * step)
        for e in np.eye(ACT)])
    np.testing.assert_allclose(jac, numeric, atol=1e-6)
    block = jac[np.ix_([0, 2], [0, 2])]
    np.testing.assert_allclose(block @ block, block, atol=1e-12)  # a projector of rank 1
    assert np.linalg.matrix_rank(block) == 1


# --- replay buffer ----------------------------------------------------------------------------

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


# --- updates ----------------------------------------------------------------------------------

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
                                 {"exploration_std_min": 5.0}, {"exploration_decay": 1.0}])
def test_config_rejects_bad_values(bad):
    with pytest.raises(ValueError):
        TD3Config(**bad)


# --- numpy policy -----------------------------------------------------------------------------

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


def test_construction_leaves_the_global_rng_alone(layer):
    state = torch.get_rng_state()
    make_agent(layer)
    assert torch.equal(state, torch.get_rng_state())
