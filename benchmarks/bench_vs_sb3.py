"""Time to 10 % below the frozen best static gains: teleopkit's trainer against Stable-Baselines3.

    NUMBA_NUM_THREADS=1 python benchmarks/bench_vs_sb3.py [--seeds 0 1] [--rounds 12]
        [--which teleopkit sb3] [--recipes fast paper] [--discounts 0.95 0.99] [--envs 16 ...]
        [--learning-rates 1e-3 ...] [--batch-sizes 512 ...] [--n-steps 1 ...]
        [--critic-actions applied raw] [--starts centre "best static"]
        [--setup paper|mixed|FILE] [--observation paper|adaptive] [--below 0.1]
        [--episode-length 10]

Same environment (:class:`~teleopkit.rl.env.FlexTeleopVectorEnv`, 16 scenarios, the recipes'
covering certificate ``tank:3``, so the same safety layer projects every action), same machine, one
run after the other. teleopkit's trainer runs its named recipes
(:data:`~teleopkit.rl.recipes.RECIPES`, ``--recipes``); SB3's TD3 its best settings found here
(:data:`SB3_BEST`: discount 0.99, learning rates 1e-3, 16 scenarios, 10 s training episodes). A
grid option given on the command line (parallel scenarios, discounts, learning rates, minibatch
sizes, episode length, the actor's start; the steps per transition and what the critics value of
teleopkit's trainer) replaces those values for both. An actor started at the best constant gains of
the covering class (``--starts "best static"``; teleopkit's ``actor_start``, for SB3 its actor's
last bias offset to play them) pays their search in its time. Common to both: batch 512 unless
given, a warm-up of one round of uniform random gains, rewards scaled by 0.01, one gradient update
per vector step of 16 transitions, observations standardised with statistics frozen from the
warm-up, the paper's network widths, Gaussian exploration of 4 gain units. After every round (one
training episode of every scenario) the deterministic actor is validated on the recipes' 16
validation scenarios, whole 40 s episodes; a run stops at the first round whose validation cost is
10 % below that of the best static gains of the frozen class there (``--below``: the fraction below
them; ``--setup`` and ``--observation`` race on another setup, for example the adaptive tuner's
``--setup mixed --observation adaptive``, the static gains searched for it). Printed per trainer,
setting and seed: that round, the wall-clock time to it (training and validations, and the search
of an actor's start; the frozen class's static gains' search, for the target, is excluded and
printed apart) and where that time went: the simulator, the safety layer's projection, the gradient
updates (SB3: its ``train`` calls, sampling included) and the validations.

What differs is only the trainer: teleopkit's TD3 (batched experience, the actor trained through
the exact projection, fused Adam) against SB3's TD3 on an SB3 ``VecEnv`` view of the same batched
environment, actions in ``[-1, 1]`` rescaled onto the gain box.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
import torch
from gymnasium import spaces
from stable_baselines3 import TD3
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.vec_env import VecEnv

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import best_static_gains
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.networks import half_range, inside_box
from teleopkit.rl.recipes import ACTOR_STARTS, RECIPES
from teleopkit.rl.training import train
from teleopkit.setup import SHIPPED_SETUPS, Setup, shipped_setup_path

RECIPE = RECIPES["paper"]
REWARD_SCALE = RECIPE.td3.reward_scale

SB3_BEST = {"discount": 0.99, "learning_rate": 1e-3, "envs": 16, "episode_length": 10.0,
            "actor_start": "centre"}
"""SB3's best settings on the paper's benchmark (searched: discounts 0.95 and 0.99, learning
rates 3e-4 to 3e-3, 16 and 64 scenarios, 10 and 40 s training episodes, minibatches of 128 and
512, the actor started at the centre of the box or at the best constant gains; batch 512 is the
grid's default)."""


SPLIT = ("simulation", "projection", "update", "validation")
"""Where a run's time goes, as both trainers report it."""


class _Reached(Exception):
    """Raised by a round callback to stop a run at its first round below the target."""


class Setting(NamedTuple):
    """One trainer's settings in the race."""

    trainer: str
    recipe: str
    seed: int
    discount: float
    learning_rate: float
    envs: int
    n_step: int
    critic_action: str
    episode_length: float
    batch_size: int
    actor_start: str


def _teleopkit(setting: Setting, rounds: int, target: float,
               config: FlexTeleopConfig) -> dict[str, float]:
    """Round, validation cost, wall time and its split at the first round below the target."""
    per_round = setting.envs * _training(config, setting).max_steps
    rate = setting.learning_rate
    recipe = RECIPES[setting.recipe]
    settings = replace(recipe, total_steps=rounds * per_round, seed=setting.seed,
                       num_envs=setting.envs, learning_starts=per_round,
                       episode_length=setting.episode_length,
                       validation_length=config.episode_length, n_step=setting.n_step,
                       buffer_size=max(recipe.buffer_size, 2 * per_round),
                       actor_start=setting.actor_start,
                       td3=replace(recipe.td3, discount=setting.discount, actor_lr=rate,
                                   critic_lr=rate, critic_action=setting.critic_action,
                                   batch_size=setting.batch_size))
    found: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as out:
        def check(done: int) -> None:
            log = pd.read_csv(f"{out}/train_log.csv")
            row = log.iloc[-1]
            found.update(round=done, cost=row["validation_cost"], wall=row["wall_time"],
                         best=log["validation_cost"].min(),
                         **{part: log[f"{part}_time"].sum() for part in SPLIT})
            if row["validation_cost"] <= target:
                raise _Reached

        try:
            train(settings, out, env_config=config, progress=False, on_round=check)
        except _Reached:
            pass
    return found


def _training(config: FlexTeleopConfig, setting: Setting) -> FlexTeleopConfig:
    """The environment of the training episodes (the task's, of the setting's length)."""
    return replace(config, episode_length=setting.episode_length)


def _sb3(setting: Setting, rounds: int, target: float,
         config: FlexTeleopConfig) -> dict[str, float]:
    """Round, validation cost, wall time and its split at the first round below the target."""
    start = time.perf_counter()
    training = _training(config, setting)
    env = _SB3View(FlexTeleopVectorEnv(setting.envs, training), setting.seed, config)
    per_round = setting.envs * training.max_steps
    half = (env.high - env.low) / 2
    model = TD3("MlpPolicy", env, learning_rate=setting.learning_rate,
                buffer_size=max(RECIPE.buffer_size, 2 * per_round),
                learning_starts=per_round, batch_size=setting.batch_size, tau=0.005,
                gamma=setting.discount, train_freq=(1, "step"), gradient_steps=1,
                policy_delay=2, target_policy_noise=0.2, target_noise_clip=0.5,
                action_noise=NormalActionNoise(np.zeros(4), RECIPE.td3.exploration_std / half),
                policy_kwargs={"net_arch": {"pi": [128, 64], "qf": [128, 64, 60, 36]}},
                seed=setting.seed, device="cpu", verbose=0)
    if setting.actor_start == "best static":
        _start_at(model, best_static_gains(config=config).gains, env.low, env.high)
    seconds = {"update": 0.0, "validation": 0.0}
    learn = model.train

    def timed_train(*args: Any, **kwargs: Any) -> None:
        began = time.perf_counter()
        learn(*args, **kwargs)
        seconds["update"] += time.perf_counter() - began

    model.train = timed_train  # type: ignore[method-assign]
    found: dict[str, float] = {}

    class Validate(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % per_round:
                return True
            began = time.perf_counter()
            cost = env.validation_cost(self.model)
            seconds["validation"] += time.perf_counter() - began
            found.update(round=self.num_timesteps // per_round, cost=cost,
                         best=min(cost, found.get("best", cost)),
                         wall=time.perf_counter() - start, **env.inner.seconds, **seconds)
            return cost > target

    model.learn(total_timesteps=rounds * per_round, callback=Validate())
    return found


def _start_at(model: Any, gains: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    """Offset the last bias of SB3's actor (and its target) so that it plays ``gains``.

    As teleopkit's tanh actor starts (:class:`~teleopkit.rl.networks.Actor`): the output
    ``tanh(z)`` rescaled onto the box, ``z`` shifted by ``artanh`` of the gains' place in it,
    1 % of the range inside an edge.
    """
    place = (inside_box(gains, low, high) - (low + high) / 2) / half_range(low, high)
    with torch.no_grad():
        model.actor.mu[-2].bias.add_(torch.as_tensor(np.arctanh(place), dtype=torch.float32))
    model.actor_target.load_state_dict(model.actor.state_dict())


class _SB3View(VecEnv):
    """An SB3 ``VecEnv`` view of a batched teleopkit environment.

    Actions in ``[-1, 1]`` rescaled onto the gain box; observations standardised with
    statistics frozen from a warm-up episode of uniform random gains; validation on the
    ``task``'s episodes.
    """

    def __init__(self, inner: FlexTeleopVectorEnv, seed: int, task: FlexTeleopConfig) -> None:
        self.inner = inner
        self.task = task
        space = inner.single_action_space
        self.low, self.high = space.low, space.high
        size = inner.single_observation_space.shape[0]
        super().__init__(inner.num_envs,
                         spaces.Box(-np.inf, np.inf, (size,), np.float32),
                         spaces.Box(-1.0, 1.0, (len(self.low),), np.float32))
        self.mean, self.std = self._warm_up_statistics(seed)
        self._seed = seed
        self._actions = np.zeros((inner.num_envs, len(self.low)))

    def _warm_up_statistics(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(seed)
        obs, _ = self.inner.reset(seed=seed)
        rows, done = [obs], False
        while not done:
            action = rng.uniform(self.low, self.high, (self.num_envs, len(self.low)))
            obs, _, terminated, truncated, _ = self.inner.step(action)
            rows.append(obs)
            done = bool(np.any(terminated | truncated))
        stacked = np.concatenate(rows)
        return stacked.mean(axis=0), np.maximum(stacked.std(axis=0), 1e-8)

    def scale(self, obs: np.ndarray) -> np.ndarray:
        return ((obs - self.mean) / self.std).astype(np.float32)

    def gains(self, action: np.ndarray) -> np.ndarray:
        return self.low + (np.clip(action, -1, 1) + 1) / 2 * (self.high - self.low)

    def reset(self) -> np.ndarray:
        obs, _ = self.inner.reset(seed=self._seed + 1)
        return self.scale(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[Any, ...]:
        obs, reward, terminated, truncated, _ = self.inner.step(self.gains(self._actions))
        done = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if done.any():
            for i in range(self.num_envs):
                infos[i] = {"terminal_observation": self.scale(obs[i]),
                            "TimeLimit.truncated": bool(truncated[i])}
            obs, *_ = self.inner.step(self._actions)  # the autoreset step
        return self.scale(obs), (REWARD_SCALE * reward).astype(np.float32), done, infos

    def validation_cost(self, model: Any) -> float:
        def controller(obs: np.ndarray) -> np.ndarray:
            return self.gains(model.predict(self.scale(obs), deterministic=True)[0])

        run = rollout(controller, RECIPE.validation_scenarios, RECIPE.validation_seed, self.task)
        return float(-run.reward.sum(axis=0).mean())

    def close(self) -> None:
        self.inner.close()

    def get_attr(self, name: str, indices: Any = None) -> list[Any]:
        return [getattr(self, name)] * self.num_envs

    def set_attr(self, name: str, value: Any, indices: Any = None) -> None:
        setattr(self, name, value)

    def env_method(self, name: str, *args: Any, indices: Any = None,
                   **kwargs: Any) -> list[Any]:
        return [getattr(self, name)(*args, **kwargs)] * self.num_envs

    def env_is_wrapped(self, wrapper_class: Any, indices: Any = None) -> list[bool]:
        return [False] * self.num_envs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    parser.add_argument("--rounds", type=int, default=12)
    parser.add_argument("--which", nargs="+", default=["teleopkit", "sb3"])
    parser.add_argument("--recipes", nargs="+", default=["fast"], choices=list(RECIPES),
                        help="teleopkit's recipes (teleopkit.rl.recipes.RECIPES)")
    parser.add_argument("--discounts", nargs="+", type=float, default=None,
                        help="discounts of both trainers [default: each one's own]")
    parser.add_argument("--envs", nargs="+", type=int, default=None,
                        help="parallel scenarios of both trainers (a round is one episode each) "
                             "[default: 16]")
    parser.add_argument("--learning-rates", nargs="+", type=float, default=None,
                        help="learning rates of actor and critics, both trainers [default: 1e-3]")
    parser.add_argument("--batch-sizes", nargs="+", type=int, default=None,
                        help="minibatch sizes of both trainers [default: 512]")
    parser.add_argument("--n-steps", nargs="+", type=int, default=None,
                        help="steps per transition of teleopkit's trainer [default: the recipe's]")
    parser.add_argument("--critic-actions", nargs="+", default=None, choices=["applied", "raw"],
                        help="what teleopkit's critics value (TD3Config.critic_action) "
                             "[default: the recipe's]")
    parser.add_argument("--starts", nargs="+", default=None, choices=list(ACTOR_STARTS),
                        help="where both trainers' actors start: the box's centre, or the best "
                             "constant gains of the covering class, their search timed "
                             "[default: the recipe's; SB3: centre]")
    parser.add_argument("--setup", default="paper", help="a shipped setup name or a file")
    parser.add_argument("--observation", default="paper", choices=["paper", "adaptive"])
    parser.add_argument("--below", type=float, default=0.1,
                        help="target: this fraction below the frozen best static gains' cost")
    parser.add_argument("--episode-length", type=float, default=None,
                        help="seconds of the training episodes of both trainers [default: each "
                             "one's own]; validation stays on whole 40 s episodes")
    args = parser.parse_args()
    torch.set_num_threads(1)
    start = time.perf_counter()
    path = shipped_setup_path(args.setup) if args.setup in SHIPPED_SETUPS else Path(args.setup)
    setup = Setup.from_file(path)
    frozen_config = FlexTeleopConfig(setup)
    static = best_static_gains(config=frozen_config).gains
    frozen = rollout(ConstantGains(static), RECIPE.validation_scenarios, RECIPE.validation_seed,
                     frozen_config)
    target = (1 - args.below) * float(-frozen.reward.sum(axis=0).mean())
    print(f"target validation cost {target:.0f} (frozen best static gains "
          f"{static.round(3).tolist()}, found in {time.perf_counter() - start:.0f} s)")
    certificate = default_certificate(setup.params, setup.network.reached_bounds, COVERING_CLASS)
    config = FlexTeleopConfig(setup, certificate, observation=args.observation)
    trainers = {"teleopkit": _teleopkit, "sb3": _sb3}
    print("\n| trainer | start | envs | episode [s] | n-step | critic values | discount "
          "| learning rate | batch | seed | round | validation cost | time to it [s] | simulation "
          "| projection | updates | validation |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.which:
        for setting in _grid(args, name):
            found = trainers[name](setting, args.rounds, target, config)
            mark = ("" if found["cost"] <= target else
                    f" (not within {args.rounds} rounds; best {found['best']:.0f})")
            split = " | ".join(f"{found[part]:.0f}" for part in SPLIT)
            label = f"{setting.trainer} {setting.recipe}".rstrip()
            print(f"| {label} | {setting.actor_start} | {setting.envs} | "
                  f"{setting.episode_length:g} | "
                  f"{setting.n_step} | {setting.critic_action} | {setting.discount:g} | "
                  f"{setting.learning_rate:g} | {setting.batch_size} | {setting.seed} | "
                  f"{found['round']:.0f} | "
                  f"{found['cost']:.0f}{mark} | {found['wall']:.0f} | {split} |", flush=True)


def _grid(args: argparse.Namespace, name: str) -> list[Setting]:
    """Every setting of the command line for one trainer (teleopkit: for each recipe).

    An option left out takes the recipe's value (SB3: :data:`SB3_BEST`). SB3 has no n-step
    option here, and its critics value the raw actions.
    """
    if name == "sb3":
        return _settings(args, "sb3", "", SB3_BEST["discount"], SB3_BEST["learning_rate"],
                         SB3_BEST["envs"], 1, "raw", SB3_BEST["episode_length"],
                         SB3_BEST["actor_start"])
    grid = []
    for recipe_name in args.recipes:
        recipe = RECIPES[recipe_name]
        grid += _settings(args, "teleopkit", recipe_name, recipe.td3.discount,
                          recipe.td3.actor_lr, recipe.num_envs, recipe.n_step,
                          recipe.td3.critic_action, recipe.episode_length, recipe.actor_start)
    return grid


def _settings(args: argparse.Namespace, trainer: str, recipe: str, discount: float, rate: float,
              envs: int, n_step: int, valued: str, length: float, start: str) -> list[Setting]:
    """One trainer's settings: the command line's grid where given, else the values passed."""
    ours = trainer == "teleopkit"
    return [Setting(trainer, recipe, seed, gamma, lr, count, n, value,
                    args.episode_length or length, batch, actor_start)
            for actor_start in args.starts or [start]
            for count in args.envs or [envs]
            for n in (args.n_steps or [n_step] if ours else [1])
            for value in (args.critic_actions or [valued] if ours else ["raw"])
            for gamma in args.discounts or [discount]
            for lr in args.learning_rates or [rate]
            for batch in args.batch_sizes or [RECIPE.td3.batch_size] for seed in args.seeds]


if __name__ == "__main__":
    main()
