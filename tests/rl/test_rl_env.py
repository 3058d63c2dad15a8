"""Gymnasium environments: API conformance, reproducibility, safety and autoreset."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import teleopkit
from teleopkit.certification.certifier import default_certificate
from teleopkit.rl import evaluation
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import (
    ENV_ID,
    FlexTeleopConfig,
    FlexTeleopEnv,
    FlexTeleopVectorEnv,
    RewardWeights,
)
from teleopkit.safety import Fallback
from teleopkit.sim.state import StateLayout

N = 2  # joints
SHORT = 0.2  # seconds: 20 control periods


def wild_actions(rng: np.random.Generator, count: int, batch: tuple[int, ...] = ()) -> np.ndarray:
    """Random gains far outside the box, with NaN and inf sprinkled in."""
    actions = rng.uniform(-100.0, 400.0, size=(count, *batch, 2 * N))
    mask = rng.random(actions.shape) < 0.05
    actions[mask] = rng.choice([np.nan, np.inf, -np.inf], size=int(mask.sum()))
    return actions


def rollout(env: FlexTeleopEnv, seed: int, actions: np.ndarray) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    observations = [obs]
    for action in actions:
        observations.append(env.step(action)[0])
    return np.array(observations)


def test_check_env_passes():
    check_env(FlexTeleopEnv(episode_length=SHORT))


def test_registered_with_gymnasium_on_import():
    assert teleopkit.rl.env.ENV_ID == ENV_ID
    env = gymnasium.make(ENV_ID, episode_length=SHORT)
    check_env(env.unwrapped)
    assert isinstance(env.unwrapped, FlexTeleopEnv)
    assert env.unwrapped.config.episode_length == SHORT
    vector = gymnasium.make_vec(ENV_ID, num_envs=3, episode_length=SHORT)
    assert isinstance(vector, FlexTeleopVectorEnv) and vector.num_envs == 3


def test_spaces_are_the_certificate_box_and_fourteen_observations():
    env = FlexTeleopEnv(episode_length=SHORT)
    box = default_certificate().box
    np.testing.assert_array_equal(env.action_space.low, box.lower)
    np.testing.assert_array_equal(env.action_space.high, box.upper)
    assert env.observation_space.shape == (14,)
    assert not env.certificate.certified  # the box is not certified, its polytope is
    assert env.safety_layer.polytope is env.certificate.polytope


def test_observation_layout():
    env = FlexTeleopEnv(episode_length=SHORT)
    obs, _ = env.reset(seed=0)
    initial = env.config.params.initial
    np.testing.assert_array_equal(obs[4:6], initial.local)  # q_l(t - T_l): the constant past
    np.testing.assert_array_equal(obs[10:12], np.asarray(initial.motor) - initial.remote)
    obs, reward, *_, info = env.step(np.array([10.0, 10.0, 30.0, 30.0]))
    theta, delayed = obs[0:2], obs[4:6]
    np.testing.assert_allclose(obs[6:8], theta - delayed)
    weights = env.config.weights
    expected = -(weights.alpha * np.sum(obs[6:8] ** 2) + weights.beta * np.sum(obs[10:12] ** 2)
                 + weights.gamma * np.sum(info["applied_action"] ** 2))
    assert reward == pytest.approx(expected)


def test_same_seed_same_observations_other_seed_differs():
    # the remote side sees the scenario only once the first delayed sample arrives (T_l < 1 s)
    actions = np.random.default_rng(0).uniform(1.0, 150.0, size=(110, 2 * N))
    first = rollout(FlexTeleopEnv(episode_length=1.5), 7, actions)
    second = rollout(FlexTeleopEnv(episode_length=1.5), 7, actions)
    np.testing.assert_array_equal(first, second)
    assert not np.array_equal(first, rollout(FlexTeleopEnv(episode_length=1.5), 8, actions))


def test_every_applied_action_is_certified():
    env = FlexTeleopEnv(episode_length=SHORT)
    env.reset(seed=1)
    polytope = env.certificate.polytope
    for action in wild_actions(np.random.default_rng(1), 60):
        *_, terminated, truncated, info = env.step(action)
        assert polytope.contains(info["applied_action"])
        assert info["fallback"] == (not np.all(np.isfinite(action)))
        assert not terminated
        if truncated:
            env.reset()
    assert env.unsafe_actions == 0


def test_non_finite_action_holds_the_previous_gains():
    env = FlexTeleopEnv(episode_length=SHORT)
    env.reset(seed=2)
    applied = env.step(np.array([10.0, 10.0, 30.0, 30.0]))[-1]["applied_action"]
    info = env.step(np.array([np.nan, 10.0, 30.0, 30.0]))[-1]
    np.testing.assert_array_equal(info["applied_action"], applied)
    assert info["fallback_flags"] == Fallback.NONFINITE_INPUT


def test_time_limit_truncates():
    env = FlexTeleopEnv(episode_length=SHORT)
    env.reset(seed=3)
    ends = []
    for _ in range(20):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        ends.append((terminated, truncated))
    assert ends[:-1] == [(False, False)] * 19 and ends[-1] == (False, True)
    assert info["time"] == pytest.approx(SHORT)


def test_leaving_the_state_bound_terminates_with_the_penalty():
    env = FlexTeleopEnv(episode_length=SHORT, state_bound=0.05, failure_penalty=123.0)
    env.reset(seed=4)
    obs, reward, terminated, truncated, _ = env.step(np.array([10.0, 10.0, 30.0, 30.0]))
    assert terminated and not truncated and reward == -123.0
    assert env.observation_space.contains(obs)


def test_energy_integrals_beyond_the_bound_do_not_end_a_stable_run():
    # under the paper's setup and moderate gains the motion stays within 12 (rad, rad/s) for
    # 20 s while the double integral of the squared local velocity passes 20: it is bookkeeping
    config = FlexTeleopConfig(episode_length=20.0, state_bound=15.0)
    run = evaluation.rollout(ConstantGains(np.array([10.0, 10.0, 30.0, 30.0])), 2, 0, config)
    layout = StateLayout(2)
    state = run.trajectory.state
    assert np.abs(state[..., :layout.bounded]).max() <= 15.0
    assert np.abs(layout.get(state, "iint_dql2")).max() > 15.0


def test_rate_bounded_certificate_limits_each_change():
    rated = dataclasses.replace(default_certificate(), method="lmi", certified=True,
                                gain_variation="rate:100")
    env = FlexTeleopEnv(episode_length=SHORT, certificate=rated)
    env.reset(seed=5)
    previous = env.step(np.array([10.0, 10.0, 30.0, 30.0]))[-1]["applied_action"]
    for action in wild_actions(np.random.default_rng(5), 10):
        applied = env.step(action)[-1]["applied_action"]
        assert np.all(np.abs(applied - previous) <= 1.0 + 1e-9)  # 100 per s over 10 ms
        previous = applied
    assert env.unsafe_actions == 0


def test_reward_weights_are_validated():
    with pytest.raises(ValueError, match="beta"):
        RewardWeights(beta=-1.0)
    with pytest.raises(TypeError):
        FlexTeleopEnv(episode_lenght=1.0)


def test_vector_env_shapes_and_next_step_autoreset():
    envs = FlexTeleopVectorEnv(num_envs=4, episode_length=0.05)
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (4, 14) and envs.observation_space.shape == (4, 14)
    assert envs.action_space.shape == (4, 4)
    for step in range(5):
        obs, reward, terminated, truncated, info = envs.step(wild_actions(
            np.random.default_rng(step), 1, (4,))[0])
        assert reward.shape == (4,) and info["applied_action"].shape == (4, 4)
        assert info["_applied_action"].all()
    assert truncated.all() and not terminated.any()
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    first, _ = envs.reset(seed=1)
    np.testing.assert_array_equal(obs, first)  # autoreset: the initial observations
    assert not reward.any() and not terminated.any() and not truncated.any() and info == {}
    assert envs.unsafe_actions == 0


def test_vector_env_failure_ends_every_episode_then_autoresets():
    envs = FlexTeleopVectorEnv(num_envs=3, episode_length=SHORT, state_bound=0.05)
    envs.reset(seed=0)
    obs, reward, terminated, truncated, _ = envs.step(envs.action_space.sample())
    assert terminated.all() and not truncated.any()
    np.testing.assert_array_equal(reward, -envs.config.failure_penalty)
    assert envs.observation_space.contains(obs)
    _, reward, terminated, truncated, _ = envs.step(envs.action_space.sample())
    assert not reward.any() and not terminated.any() and not truncated.any()


def test_vector_env_of_one_matches_the_single_env():
    actions = np.random.default_rng(3).uniform(1.0, 150.0, size=(10, 2 * N))
    single = rollout(FlexTeleopEnv(episode_length=SHORT), 11, actions)
    envs = FlexTeleopVectorEnv(num_envs=1, episode_length=SHORT)
    batched = [envs.reset(seed=11)[0][0]] + [envs.step(a[None])[0][0] for a in actions]
    np.testing.assert_allclose(np.array(batched), single, rtol=0, atol=1e-12)


def test_stable_baselines3_td3_trains_a_few_hundred_steps():
    sb3 = pytest.importorskip("stable_baselines3")
    env = gymnasium.wrappers.RescaleAction(FlexTeleopEnv(episode_length=1.0), -1.0, 1.0)
    model = sb3.TD3("MlpPolicy", env, learning_starts=100, batch_size=64,
                    policy_kwargs={"net_arch": [32, 32]}, seed=0, verbose=0)
    model.learn(total_timesteps=300)
    assert env.unwrapped.unsafe_actions == 0
