"""The adaptive observation: what it measures, and that it carries no clock."""

from __future__ import annotations

import numpy as np

from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.features import AdaptiveObservation, observation_size
from teleopkit.sim.state import StateLayout


def test_its_entries_are_the_measured_signals():
    layout = StateLayout(2)
    rng = np.random.default_rng(0)
    state = rng.normal(size=(3, layout.size))
    received = rng.normal(size=(3, 2))
    features = AdaptiveObservation(2, 0.01)
    first = features.start(state, received, np.full(3, 0.7))
    later = received + 0.01 * np.array([1.0, -2.0])
    obs = features.step(state, later, np.full(3, 0.6))
    assert first.shape == obs.shape == (3, observation_size("adaptive", 2))
    get = layout.get
    blocks = np.split(obs[:, :16], 8, axis=1)
    np.testing.assert_allclose(blocks[2], get(state, "dqr"))
    np.testing.assert_allclose(blocks[4], np.tile([1.0, -2.0], (3, 1)))  # received rate
    np.testing.assert_allclose(blocks[6], get(state, "theta") - get(state, "qr"))
    np.testing.assert_allclose(blocks[7], get(state, "dtheta") - get(state, "dqr"))
    np.testing.assert_allclose(obs[:, -1], 0.6)


def test_it_forgets_the_past_and_does_not_grow_with_time():
    """Held at one state, the observation converges to a constant: no clock in it."""
    layout = StateLayout(2)
    state = np.zeros((1, layout.size))
    state[:, layout.slice("theta")] = 0.1
    features = AdaptiveObservation(2, 0.01)
    features.start(np.zeros_like(state), np.zeros((1, 2)), np.zeros(1))
    seen = [features.step(state, np.zeros((1, 2)), np.zeros(1)) for _ in range(2000)]
    np.testing.assert_allclose(seen[-1], seen[-2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(seen[-1][0, -7:-5], np.log10(0.0 + 1e-12))  # motion level


def test_the_environment_observes_what_its_space_says():
    config = FlexTeleopConfig(episode_length=0.2, observation="adaptive")
    env = FlexTeleopVectorEnv(3, config)
    obs, _ = env.reset(seed=1)
    assert obs.shape == (3, *env.single_observation_space.shape)
    obs, *_ = env.step(np.tile([5.0, 5.0, 20.0, 20.0], (3, 1)))
    assert obs.shape == (3, *env.single_observation_space.shape)


def test_a_decision_holds_the_gains_and_sums_the_periods_rewards():
    from teleopkit.rl.controllers import ConstantGains, HeldController
    from teleopkit.rl.evaluation import rollout

    gains = np.array([5.0, 5.0, 20.0, 20.0])
    fine = FlexTeleopVectorEnv(2, FlexTeleopConfig(episode_length=0.2))
    coarse = FlexTeleopVectorEnv(2, FlexTeleopConfig(episode_length=0.2, decision_period=5))
    fine.reset(seed=3)
    coarse.reset(seed=3)
    assert coarse.config.max_steps == 4
    summed = sum(fine.step(np.tile(gains, (2, 1)))[1] for _ in range(5))
    np.testing.assert_allclose(coarse.step(np.tile(gains, (2, 1)))[1], summed, rtol=1e-12)
    asked = []

    def rising(obs):
        asked.append(len(asked))
        return np.tile(gains + len(asked), (len(obs), 1))

    run = rollout(HeldController(rising, 5), 2, 3, FlexTeleopConfig(episode_length=0.2))
    assert len(asked) == 4  # 20 periods, a decision every 5
    np.testing.assert_array_equal(run.raw[:, 0, 0], np.repeat(gains[0] + np.arange(1, 5), 5))
    steady = rollout(ConstantGains(gains + 1), 2, 3, FlexTeleopConfig(episode_length=0.2))
    np.testing.assert_allclose(run.reward[:5], steady.reward[:5], rtol=1e-12)
