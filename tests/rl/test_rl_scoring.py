"""The agent's observation, reward and failure check, against their definitions in numpy."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.rl.scoring import OBSERVATION, RewardWeights, observation, score
from teleopkit.sim.state import FIELDS, StateLayout

WEIGHTS = RewardWeights(alpha=3.0, beta=700.0, gamma=2e-3)


def batch(rng: np.random.Generator, size: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Random states ``(size, 12 n)`` and delayed positions ``(size, n)``, entries within 2."""
    return (rng.uniform(-2.0, 2.0, size=(size, StateLayout(n).size)),
            rng.uniform(-2.0, 2.0, size=(size, n)))


def reward_by_definition(e_track, e_damp, action, weights=WEIGHTS):
    return -(weights.alpha * np.sum(e_track ** 2, axis=-1)
             + weights.beta * np.sum(e_damp ** 2, axis=-1)
             + weights.gamma * np.sum(action ** 2, axis=-1))


@pytest.mark.parametrize("n", [1, 2, 3])
def test_observation_blocks_are_the_named_state_blocks(n):
    state, delayed = batch(np.random.default_rng(n), 5, n)
    layout = StateLayout(n)
    theta = layout.get(state, "theta")
    expected = {"theta": theta, "dtheta": layout.get(state, "dtheta"), "ql_delayed": delayed,
                "e_track": theta - delayed, "int_e_track": layout.get(state, "int_track"),
                "e_damp": theta - layout.get(state, "qr"),
                "int_e_damp": layout.get(state, "int_damp")}
    obs = observation(state, delayed)
    assert obs.shape == (5, len(OBSERVATION) * n)
    for k, name in enumerate(OBSERVATION):
        np.testing.assert_array_equal(obs[:, k * n:(k + 1) * n], expected[name], err_msg=name)


def test_reward_of_any_leading_shape_and_broadcast_gains():
    rng = np.random.default_rng(1)
    e_track, e_damp = rng.normal(size=(2, 4, 3, 2))
    action = rng.uniform(0, 150, size=(3, 4))  # one row per scenario, shared by the periods
    got = WEIGHTS.reward(e_track, e_damp, action)
    assert got.shape == (4, 3)
    np.testing.assert_allclose(got, reward_by_definition(e_track, e_damp, action), rtol=1e-15)
    assert WEIGHTS.reward(e_track[0, 0], e_damp[0, 0], action[0]).shape == ()
    assert WEIGHTS.reward(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 4))).shape == (0,)


def test_score_is_observation_reward_and_the_bound():
    rng = np.random.default_rng(2)
    state, delayed = batch(rng, 6, 2)
    action = rng.uniform(0, 150, size=(6, 4))
    bound = 2.5
    state[1, 3] = np.nan
    state[2, 20] = -np.inf
    state[3, 0] = 2.6  # beyond the bound
    state[4, 5] = bound  # on the bound: admissible
    obs, reward, failed, failures = score(state, delayed, action, WEIGHTS, bound)
    np.testing.assert_array_equal(obs, observation(state, delayed))
    n = 2
    e_track = obs[:, OBSERVATION.index("e_track") * n:][:, :n]
    e_damp = obs[:, OBSERVATION.index("e_damp") * n:][:, :n]
    np.testing.assert_array_equal(reward, WEIGHTS.reward(e_track, e_damp, action))
    np.testing.assert_array_equal(failed, [False, True, True, True, False, False])
    assert failures == 3


@pytest.mark.parametrize("n", [1, 2])
def test_the_bound_covers_motion_and_integrated_errors_not_the_energy_integrals(n):
    # the double integral of a squared velocity grows linearly in time on a stable run: a
    # bound on it would end runs that never diverged (found from starts of +-0.6 rad)
    layout, bound = StateLayout(n), 10.0
    state = np.zeros((len(FIELDS) + 1, layout.size))
    for row, name in enumerate(FIELDS):
        state[row, layout.slice(name)] = 3 * bound
    state[-1, layout.slice("iint_dtheta2")] = np.nan  # not finite: a failure wherever it is
    bounded = {"ql", "dql", "qr", "dqr", "theta", "dtheta", "int_track", "int_damp"}
    expected = [name in bounded for name in FIELDS] + [True]
    failed = score(state, np.zeros((len(state), n)), np.ones((len(state), 2 * n)), WEIGHTS,
                   bound).failed
    np.testing.assert_array_equal(failed, expected)
    over_time = np.stack([np.zeros_like(state), state])  # (time, runs, entries)
    np.testing.assert_array_equal(layout.escaped(over_time, bound), expected)


def test_score_reads_a_strided_view_of_the_delayed_signals():
    rng = np.random.default_rng(3)
    state, _ = batch(rng, 4, 2)
    delayed = rng.normal(size=(4, 2, 2))  # [q_l(t - T_l), theta(t - T_r)] as the simulator gives
    action = np.full((4, 4), 10.0)
    got = score(state, delayed[:, 0], action, WEIGHTS, 10.0).obs
    np.testing.assert_array_equal(got, observation(state, np.ascontiguousarray(delayed[:, 0])))


def test_errors_of_different_joint_counts_are_refused():
    with pytest.raises(ValueError, match="same number of joints"):
        WEIGHTS.reward(np.zeros((3, 2)), np.zeros((3, 1)), np.zeros((3, 4)))


@pytest.mark.parametrize(("state", "delayed", "action"), [
    (np.zeros((2, 24)), np.zeros((3, 2)), np.zeros((2, 4))),  # batches differ
    (np.zeros((2, 23)), np.zeros((2, 2)), np.zeros((2, 4))),  # not 12 n entries
    (np.zeros(24), np.zeros(2), np.zeros(4)),  # no batch axis
    (np.zeros((2, 24)), np.zeros((2, 2)), np.zeros((2, 3))),  # gains of the wrong size
])
def test_mismatched_shapes_are_refused(state, delayed, action):
    with pytest.raises(ValueError, match="shape"):
        score(state, delayed, action, WEIGHTS, 1.0)
