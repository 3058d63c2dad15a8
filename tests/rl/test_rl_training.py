"""Training loop: learning on a tiny problem, logs, checkpoints, exact resume after a kill."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
import torch

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.policy import GainPolicy
from teleopkit.rl.recipes import RECIPES
from teleopkit.rl.td3 import TD3, TD3Config
from teleopkit.rl.training import (
    BEST_POLICY,
    CHECKPOINT,
    LOG,
    POLICY,
    TrainConfig,
    _Run,
    load_checkpoint,
    train,
)

torch.set_num_threads(1)

# 4 scenarios x 10 periods = 40 transitions per round
TINY = TrainConfig(total_steps=40 * 12, num_envs=4, seed=5, episode_length=0.1,
                   learning_starts=80, buffer_size=2000, td3=TD3Config(batch_size=32))


def flat(agent):
    modules = [agent.actor, agent.critics, agent.actor_target, agent.critic_targets]
    return torch.cat([p.detach().flatten() for m in modules for p in m.parameters()])


def test_short_training_improves_the_return():
    """Falsifiable: over the first 0.3 s (before any delayed operator motion reaches the remote
    side, so every scenario is the same control problem: the opening transient) the initial
    actor asks for the centre of the box (K_r = 25.5, B_r = 75.5) and costs 2188, the best
    constant gains about 1833 (0.84 times). 2 160 updates must cut the initial cost by 6 %."""
    config = TrainConfig(total_steps=8 * 30 * 20, num_envs=8, seed=1, episode_length=0.3,
                         learning_starts=8 * 30 * 2, updates_per_step=4, buffer_size=20_000,
                         td3=TD3Config(batch_size=64, actor_lr=1e-3, critic_lr=1e-3))
    result = train(config, progress=False)
    env_config = FlexTeleopConfig(episode_length=0.3)
    initial = TD3.for_env(FlexTeleopVectorEnv(1, env_config), config.td3).policy()
    before = rollout(initial, 4, 99, env_config).metrics()["cost"].mean()
    after = rollout(result.policy, 4, 99, env_config).metrics()["cost"].mean()
    assert before == pytest.approx(2188, rel=1e-3)
    assert after < 0.94 * before, (before, after)


def test_log_is_a_readable_csv_with_one_row_per_round(tmp_path):
    result = train(TINY, tmp_path, progress=False)
    log = pd.read_csv(tmp_path / LOG)
    assert list(log.columns) == ["step", "round", "episode_return", "critic_loss", "actor_loss",
                                 "exploration_std", "validation_cost", "wall_time",
                                 "unsafe_actions", "simulation_time", "projection_time",
                                 "update_time", "validation_time"]
    assert log["step"].tolist() == [40 * k for k in range(1, 13)]
    # learning starts with the last step of round 2 (80 transitions)
    assert log["critic_loss"].iloc[:1].isna().all() and log["critic_loss"].iloc[1:].notna().all()
    assert (log["unsafe_actions"] == 0).all() and log["wall_time"].is_monotonic_increasing
    assert np.all(log["episode_return"] < 0)
    # the split of each round's time: parts of it, no updates before learning starts
    split = log[["simulation_time", "projection_time", "update_time", "validation_time"]]
    assert (split >= 0).all().all() and (split.iloc[:, [0, 1, 3]] > 0).all().all()
    assert log["update_time"].iloc[0] == 0 and (log["update_time"].iloc[1:] > 0).all()
    rounds = log["wall_time"].diff().fillna(log["wall_time"].iloc[0])
    assert (split.sum(axis=1) <= rounds + 1e-9).all()
    pd.testing.assert_frame_equal(log, result.log, check_dtype=False)
    assert (tmp_path / POLICY).exists() and (tmp_path / "config.json").exists()
    best = GainPolicy.load(tmp_path / BEST_POLICY)
    assert best.metadata["validation_cost"] == log["validation_cost"].min()
    assert best.metadata["rounds"] == log["round"][log["validation_cost"].idxmin()]
    assert result.best_policy is not None
    obs = np.random.default_rng(0).normal(size=(3, 14))
    np.testing.assert_array_equal(result.best_policy(obs), best(obs))
    last = int(log["validation_cost"].idxmin()) == len(log) - 1
    assert np.array_equal(result.policy(obs), best(obs)) == last


def test_seeded_runs_are_reproducible():
    a = train(TINY, progress=False)
    b = train(TINY, progress=False)
    c = train(replace(TINY, seed=6), progress=False)
    assert torch.equal(flat(a.agent), flat(b.agent))
    assert not torch.equal(flat(a.agent), flat(c.agent))


@pytest.mark.parametrize("valued", ["applied", "raw"])
def test_the_buffer_stores_what_the_critics_value(valued):
    from teleopkit.rl.training import _Run

    config = replace(TINY, td3=replace(TINY.td3, critic_action=valued, exploration_std=30.0))
    run = _Run(config, None)
    for _ in range(3):  # the warm-up, then two rounds of the actor plus wide noise
        run.run_round(lambda steps: None)
    stored = run.buffer.action[:len(run.buffer)]
    inside = run.env.safety_layer.polytope.contains(stored, tol=1e-3)  # float32 storage
    assert np.all((stored >= run.low - 1e-6) & (stored <= run.high + 1e-6))
    # applied gains are all certified; raw ones (clipped to the box) are not
    assert inside.all() if valued == "applied" else not inside.all()
    assert run.counters.unsafe_actions == 0  # the environment projected every one


@pytest.mark.parametrize("n_step", [1, 4])
def test_resume_continues_bit_identically(tmp_path, n_step):
    config = replace(TINY, n_step=n_step)  # n-step: the window is empty at a round's end
    straight = train(config, tmp_path / "straight", progress=False)
    half = replace(config, total_steps=config.total_steps // 2)
    train(half, tmp_path / "split", progress=False)
    assert load_checkpoint(tmp_path / "split" / CHECKPOINT)["counters"]["rounds"] == 6
    resumed = train(config, tmp_path / "split", resume=True, progress=False)
    assert torch.equal(flat(straight.agent), flat(resumed.agent))
    obs = np.random.default_rng(0).normal(size=(3, 14))
    np.testing.assert_array_equal(straight.best_policy(obs), resumed.best_policy(obs))
    columns = ["step", "episode_return", "critic_loss", "actor_loss", "validation_cost"]
    pd.testing.assert_frame_equal(straight.log[columns], resumed.log[columns])


def test_interrupted_save_keeps_the_previous_checkpoint(tmp_path, monkeypatch):
    saves = []
    real_replace = os.replace

    def flaky_replace(src, dst):
        if str(dst).endswith(CHECKPOINT):
            saves.append(dst)
            if len(saves) == 5:
                raise KeyboardInterrupt  # dies between writing the temporary and the move
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", flaky_replace)
    with pytest.raises(KeyboardInterrupt):
        train(TINY, tmp_path, progress=False)
    monkeypatch.setattr(os, "replace", real_replace)
    assert load_checkpoint(tmp_path / CHECKPOINT)["counters"]["rounds"] == 4
    resumed = train(TINY, tmp_path, resume=True, progress=False)
    assert torch.equal(flat(resumed.agent), flat(train(TINY, progress=False).agent))


KILLED_RUN = textwrap.dedent("""
    import sys, time, torch
    from dataclasses import replace
    from teleopkit.rl.td3 import TD3Config
    from teleopkit.rl.training import TrainConfig, train
    torch.set_num_threads(1)
    config = TrainConfig(total_steps=40 * 12, num_envs=4, seed=5, episode_length=0.1,
                         learning_starts=80, buffer_size=2000, td3=TD3Config(batch_size=32))
    train(config, sys.argv[1], progress=False, on_round=lambda r: time.sleep(0.3))
""")


def test_killed_process_resumes_to_the_same_parameters(tmp_path):
    script = tmp_path / "run.py"
    script.write_text(KILLED_RUN)
    out = tmp_path / "run"
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    process = subprocess.Popen([sys.executable, str(script), str(out)], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None:
            # the log of round 4 is written after the checkpoint of round 3
            if (out / LOG).exists() and len(pd.read_csv(out / LOG)) >= 4:
                break
            time.sleep(0.05)
        assert process.poll() is None, process.stderr.read().decode() if process.stderr else ""
        process.send_signal(signal.SIGKILL)
    finally:
        process.wait()
    rounds = load_checkpoint(out / CHECKPOINT)["counters"]["rounds"]  # loads: not corrupt
    assert 3 <= rounds < 12
    resumed = train(TINY, out, resume=True, progress=False)
    assert torch.equal(flat(resumed.agent), flat(train(TINY, progress=False).agent))
    assert len(pd.read_csv(out / LOG)) == 12


def test_existing_checkpoint_needs_resume_and_the_same_settings(tmp_path):
    train(replace(TINY, total_steps=80), tmp_path, progress=False)
    with pytest.raises(ValueError, match="resume"):
        train(TINY, tmp_path, progress=False)
    with pytest.raises(ValueError, match=r"other settings \(seed\): seed was 5, now 9"):
        train(replace(TINY, seed=9), tmp_path, resume=True, progress=False)
    longer = train(replace(TINY, total_steps=160), tmp_path, resume=True, progress=False)
    assert int(longer.log["step"].iloc[-1]) == 160  # only the length changed: it continues


def test_validation_runs_the_episodes_of_its_own_length():
    """Training on 0.1 s episodes, validated on 0.3 s ones: every logged validation cost is the
    cost of that round's actor over 0.3 s, not 0.1 s (the best policy's cost is recomputed)."""
    config = replace(TINY, total_steps=40 * 4, validation_length=0.3, validation_scenarios=4)
    result = train(config, progress=False)
    assert result.best_policy is not None
    log = result.log
    best = log["validation_cost"].min()

    def cost(length):
        env_config = FlexTeleopConfig(episode_length=length)
        return rollout(result.best_policy, 4, config.validation_seed,
                       env_config).metrics()["cost"].mean()

    assert cost(0.3) == pytest.approx(best, rel=1e-9)
    assert cost(0.1) < 0.9 * best  # a third of the episode costs visibly less
    assert (log["step"] == [40 * k for k in range(1, 5)]).all()  # rounds of 0.1 s


def test_a_checkpoint_without_a_later_setting_resumes_at_its_default(tmp_path):
    """A fingerprint written before a setting existed matches that setting's default."""
    train(replace(TINY, total_steps=80), tmp_path, progress=False)
    state = load_checkpoint(tmp_path / CHECKPOINT)
    fingerprint = state["fingerprint"]
    assert fingerprint.pop("validation_length") is None
    assert fingerprint.pop("actor_start") == "centre"
    assert fingerprint["td3"].pop("output_map") == "softplus"
    torch.save(state, tmp_path / CHECKPOINT)
    resumed = train(replace(TINY, total_steps=120), tmp_path, resume=True, progress=False)
    assert int(resumed.log["step"].iloc[-1]) == 120


def _dead_pid() -> int:
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    return int(child.stdout)


def test_a_directory_in_use_is_refused_and_a_killed_runs_lock_taken_over(tmp_path):
    import json
    import socket

    from teleopkit.files import RunLocked
    from teleopkit.rl.training import LOCK

    lock = tmp_path / LOCK
    lock.write_text(json.dumps({"pid": os.getppid(), "host": socket.gethostname()}))
    with pytest.raises(RunLocked, match=f"in use by another run \\(process {os.getppid()}"):
        train(replace(TINY, total_steps=40), tmp_path, progress=False)
    assert not (tmp_path / CHECKPOINT).exists()  # refused before any work
    lock.write_text(json.dumps({"pid": _dead_pid(), "host": socket.gethostname()}))
    train(replace(TINY, total_steps=40), tmp_path, progress=False)
    assert (tmp_path / CHECKPOINT).exists() and not lock.exists()


@pytest.mark.parametrize("bad", [{"total_steps": 0}, {"num_envs": 0}, {"n_step": 0},
                                 {"learning_starts": 1}, {"episode_length": 0.0}, {"seed": -1},
                                 {"validation_scenarios": -1}, {"validation_length": 0.0},
                                 {"validation_length": float("nan")}])
def test_config_rejects_bad_values(bad):
    with pytest.raises(ValueError):
        replace(TINY, **bad)


def test_config_round_trips_through_plain_data():
    assert TrainConfig.from_dict(TINY.to_dict()) == TINY
    for recipe in RECIPES.values():
        assert TrainConfig.from_dict(recipe.to_dict()) == recipe


def _explored_stiffness(exploration, variation, warm):
    """The stiffness exploration of two steps of one episode, ``(2, scenarios, joints)``: the
    uniform gains of the warm-up, else the noise added to the actor's gains."""
    config = replace(TINY, stiffness_exploration=exploration,
                     learning_starts=TINY.learning_starts if warm else TINY.num_envs)
    run = _Run(config, FlexTeleopConfig(certificate=default_certificate(variation=variation)))
    if not warm:
        run.counters.step = config.learning_starts
    obs, _ = run.env.reset(seed=0)
    run._draw_held()
    offset = 0 if warm else run.agent.act(obs)[:, :2]  # the exploration alone
    return np.stack([run._actions(obs)[:, :2] - offset for _ in range(2)])


@pytest.mark.parametrize("warm", [True, False])
def test_stiffness_exploration_is_held_per_episode_or_drawn_per_step(warm):
    """Under a tank the stiffness explores once per episode (the same on both joints), unless
    asked per step; under a frozen class every gain explores per step."""
    held = _explored_stiffness("episode", "tank:3", warm)
    np.testing.assert_array_equal(held[0], held[1])
    np.testing.assert_array_equal(held[..., 0], held[..., 1])
    assert np.unique(held[0, :, 0]).size == TINY.num_envs  # a draw per scenario
    for stepped in (_explored_stiffness("step", "tank:3", warm),
                    _explored_stiffness("episode", "frozen", warm)):
        assert np.all(stepped[0] != stepped[1])


def test_stiffness_exploration_must_be_named():
    with pytest.raises(ValueError, match="stiffness_exploration must be 'episode' or 'step'"):
        replace(TINY, stiffness_exploration="round")


STARTED = replace(TINY, actor_start="best static")


@pytest.fixture(scope="module")
def best_static_tiny():
    """The best constant gains of the tiny problem's class on its episodes."""
    from teleopkit.rl.baselines import best_static_gains

    return best_static_gains(config=FlexTeleopConfig(episode_length=TINY.episode_length)).gains


def test_the_actor_can_start_from_the_best_constant_gains(best_static_tiny):
    """Before any update the actor plays the searched gains (softplus: its small last layer);
    the policy records them."""
    untrained = train(replace(STARTED, total_steps=40, learning_starts=40), progress=False)
    centre = train(replace(TINY, total_steps=40, learning_starts=40), progress=False)
    env_config = FlexTeleopConfig(episode_length=TINY.episode_length)
    obs, _ = FlexTeleopVectorEnv(5, env_config).reset(seed=0)
    # a gain on the box's edge starts 1 % of the range inside it
    low, high = np.array([1.0, 1.0, 1.0, 1.0]), np.array([50.0, 50.0, 150.0, 150.0])
    start = np.clip(best_static_tiny, low + 0.01 * (high - low), high - 0.01 * (high - low))
    gains = untrained.policy(obs)
    np.testing.assert_allclose(gains, np.broadcast_to(start, gains.shape), rtol=0.05)
    assert not np.allclose(centre.policy(obs), gains, rtol=0.05)
    np.testing.assert_array_equal(untrained.policy.metadata["start_gains"], start)
    assert "start_gains" not in centre.policy.metadata


def test_a_started_run_resumes_without_searching_again(tmp_path, monkeypatch):
    straight = train(STARTED, tmp_path / "straight", progress=False)
    train(replace(STARTED, total_steps=STARTED.total_steps // 2), tmp_path / "split",
          progress=False)

    def refuse(*args, **kwargs):
        raise AssertionError("a resumed run searched its start again")

    monkeypatch.setattr("teleopkit.rl.baselines.best_static_gains", refuse)
    resumed = train(STARTED, tmp_path / "split", resume=True, progress=False)
    assert torch.equal(flat(straight.agent), flat(resumed.agent))
    assert resumed.policy.metadata["start_gains"] == straight.policy.metadata["start_gains"]
    assert resumed.best_policy.metadata["start_gains"] == resumed.policy.metadata["start_gains"]


def test_start_gains_on_the_box_edge_move_inside_it(monkeypatch):
    from teleopkit.rl.baselines import StaticGains

    corner = np.array([1.0, 50.0, 1.0, 150.0])  # the default box's edges

    def on_the_edges(*args, **kwargs):
        return StaticGains(corner, 0.0, corner, 0.0, 1)

    monkeypatch.setattr("teleopkit.rl.baselines.best_static_gains", on_the_edges)
    run = _Run(replace(STARTED, td3=TD3Config(output_map="tanh")), None)
    np.testing.assert_allclose(run.start_gains, [1.49, 49.51, 2.49, 148.51])


@pytest.mark.parametrize("change, message", [
    ({"actor_start": "static"}, "actor_start must be one of 'centre', 'best static'"),
    ({"actor_start": "best static", "td3": TD3Config(start=(4.0, 4.0, 10.0, 18.0))},
     "set one of the two"),
])
def test_an_unknown_or_doubly_given_start_is_refused(change, message):
    with pytest.raises(ValueError, match=message):
        replace(TINY, **change)
