"""Training loop of the TD3 gain tuner: batched experience, atomic checkpoints, exact resume.

Experience comes from one :class:`~teleopkit.rl.env.FlexTeleopVectorEnv` of ``num_envs`` scenarios
simulated together. Its sub-environments share the clock, so training proceeds in *rounds*: one
episode of every sub-environment (``num_envs * episode_length / control_period`` transitions). At
a round boundary the whole state of training is the agent, the replay buffer, three generators
and a few counters, so checkpoints are written there (every ``checkpoint_every`` rounds and at the
end) and a resumed run continues bit for bit as if it had never stopped: an interruption loses at
most the rounds since the last checkpoint. The training length ``total_steps`` (transitions over
all sub-environments) is rounded up to whole rounds.

Per vector step: the actor's raw gains plus Gaussian noise (uniform random gains in the box
during the first ``learning_starts`` transitions) go to the environment, which projects them onto
the certified set; the transition with the *applied* action enters the buffer; then
``updates_per_step`` TD3 updates run. The observation standardisation of the networks is fixed
from the buffer when learning starts. The exploration standard deviation decays with the number
of vector steps (each sub-environment's own step count). After each round the deterministic actor
is scored on fixed validation scenarios (``validation_scenarios``, seed ``validation_seed``,
episodes of ``validation_length``) and the best one is kept: the policy's held-out cost
fluctuates by several per cent from one round to the next.

Files in ``out_dir``: ``checkpoint.pt`` (``torch.save``; loads with ``weights_only=True``),
``certificate.json`` (the certificate trained under), ``train_log.csv`` (one row per round: ``step,
round, episode_return, critic_loss, actor_loss, exploration_std, validation_cost, wall_time,
unsafe_actions, simulation_time, projection_time, update_time, validation_time``; the episode
return is that of the exploring policy, averaged over the sub-environments; ``unsafe_actions``
counts applied actions outside the certified set, cumulatively, and must stay 0; ``wall_time`` is
cumulative (from the search of the actor's start, with ``actor_start="best static"``), the four
last split the round's time: the simulator's periods, the safety layer, the
TD3 updates and the validation), ``policy.npz`` (the last actor as a
:class:`~teleopkit.rl.td3.GainPolicy`), ``best_policy.npz`` (the best by validation) and
``config.json``. Each is written to a temporary file in the same directory and moved into place
with :func:`os.replace`, so a kill at any moment leaves either the previous or the new complete
file.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from gymnasium.spaces import Box

from teleopkit.files import atomic_write, run_lock
from teleopkit.rl.controllers import HeldController
from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.rl.networks import inside_box
from teleopkit.rl.policy import GainPolicy
from teleopkit.rl.recipes import TrainConfig
from teleopkit.rl.replay import NStepWindow, ReplayBuffer
from teleopkit.rl.td3 import TD3

__all__ = ["BEST_POLICY", "CERTIFICATE", "CHECKPOINT", "CONFIG", "LOG", "POLICY", "TrainConfig",
           "TrainResult", "load_checkpoint", "train"]

CHECKPOINT = "checkpoint.pt"
"""File name of the checkpoint in the output directory."""
LOG = "train_log.csv"
"""File name of the training log."""
POLICY = "policy.npz"
"""File name of the exported policy."""

_RESULT_NEUTRAL = ("total_steps", "checkpoint_every")
"""Fields that do not change what a round computes (may differ on resume)."""

BEST_POLICY = "best_policy.npz"
"""File name of the best policy by validation cost."""

CONFIG = "config.json"
"""File name of the training settings (:meth:`TrainConfig.to_dict`) in the output directory."""

CERTIFICATE = "certificate.json"
"""File name of the certificate trained under, in the output directory."""

LOCK = ".lock"
"""Lock file of a directory a training run is using (:func:`~teleopkit.files.run_lock`)."""


@dataclass
class _Counters:
    """Progress of a run (all of it is in the checkpoint)."""

    step: int = 0
    vector_steps: int = 0
    rounds: int = 0
    wall_time: float = 0.0
    unsafe_actions: int = 0
    best_validation: float = math.inf
    best_round: int = 0
    normalised: bool = False
    log: list[dict[str, float]] = field(default_factory=list)


@dataclass(frozen=True)
class TrainResult:
    """What :func:`train` returns.

    Attributes
    ----------
    agent : TD3
        The trained agent.
    log : pandas.DataFrame
        One row per round (the columns of ``train_log.csv``).
    policy : GainPolicy
        The final actor as a numpy policy.
    best_policy : GainPolicy or None
        The actor of the round with the lowest validation cost (None without validation).
    """

    agent: TD3
    log: pd.DataFrame
    policy: GainPolicy
    best_policy: GainPolicy | None


class _Run:
    """One training run: environment, agent, buffer, generators and counters."""

    def __init__(self, config: TrainConfig, env_config: FlexTeleopConfig | None,
                 search_start: bool = True, progress: bool = False) -> None:
        self.config = config
        env_config = replace(env_config or FlexTeleopConfig(),
                             episode_length=config.episode_length)
        self.env = FlexTeleopVectorEnv(config.num_envs, env_config)
        self.validation_config = replace(
            env_config, decision_period=1,
            episode_length=config.validation_length or config.episode_length)
        agent_seed, buffer_seed, explore_seed, env_seed = np.random.SeedSequence(
            config.seed).generate_state(4)
        self.env_seed = int(env_seed)
        space = self.env.single_action_space
        assert isinstance(space, Box)
        self.low, self.high = space.low, space.high
        searching = time.perf_counter()
        self.start_gains = self._start_gains(progress) if search_start else None
        searched = time.perf_counter() - searching
        td3 = (config.td3 if self.start_gains is None
               else replace(config.td3, start=tuple(self.start_gains.tolist())))
        self.agent = TD3.for_env(self.env, td3, seed=int(agent_seed))
        obs_dim = int(np.prod(self.env.single_observation_space.shape or (0,)))
        self.buffer = ReplayBuffer(config.buffer_size, obs_dim, len(self.low), int(buffer_seed))
        self.window = NStepWindow(config.n_step, config.td3.discount)
        self.explore = np.random.default_rng(explore_seed)
        self.counters = _Counters(wall_time=searched if self.start_gains is not None else 0.0)
        self.best_actor: dict[str, torch.Tensor] | None = None
        self.held_uniform: np.ndarray | None = None
        self.held_noise: np.ndarray | None = None

    def _start_gains(self, progress: bool) -> np.ndarray | None:
        """The gains the actor starts from, when searched (``actor_start="best static"``).

        The best constant gains of the training class, searched on the task's episodes, moved
        1 % of the box's range inside it where they lie on its edge (the output maps reach the
        edges only in the limit).
        """
        if self.config.actor_start == "centre":
            return None
        from teleopkit.rl.baselines import best_static_gains

        gains = best_static_gains(config=self.validation_config, progress=progress).gains
        return inside_box(gains, self.low, self.high)

    def fingerprint(self) -> dict[str, Any]:
        """Everything that determines the results (compared on resume)."""
        data = {k: v for k, v in self.config.to_dict().items() if k not in _RESULT_NEUTRAL}
        env_config = self.env.config
        data["reward_weights"] = asdict(env_config.weights)
        data["certificate"] = self.env.certificate.gain_variation
        data["polytope_h"] = self.env.safety_layer.polytope.h.tolist()
        data["control_period"] = env_config.control_period
        data["dt"] = env_config.dt
        data["setup"] = env_config.setup.fingerprint
        data["observation"] = env_config.observation
        data["decision_period"] = env_config.decision_period
        return json.loads(json.dumps(data))

    def state_dict(self) -> dict[str, Any]:
        """The checkpoint's content."""
        return {"version": 1, "fingerprint": self.fingerprint(),
                "agent": self.agent.state_dict(), "buffer": self.buffer.state_dict(),
                "explore_rng": self.explore.bit_generator.state,
                "env_rng": self.env.np_random.bit_generator.state,
                "torch_rng": torch.get_rng_state(), "counters": asdict(self.counters),
                "best_actor": self.best_actor,
                "start_gains": None if self.start_gains is None else self.start_gains.tolist()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a checkpoint written by the same configuration."""
        current = self.fingerprint()
        recorded = _at_defaults(state.get("fingerprint") or {})
        names = [key for key in dict.fromkeys([*recorded, *current])
                 if recorded.get(key) != current.get(key)]
        if names:
            first = names[0]
            raise ValueError(f"the checkpoint was written with other settings ({', '.join(names)}"
                             f"): {first} was {_short(recorded.get(first))}, now "
                             f"{_short(current.get(first))}; only total_steps and "
                             "checkpoint_every may change on resume (or use a new directory)")
        self.agent.load_state_dict(state["agent"])
        self.buffer.load_state_dict(state["buffer"])
        self.explore.bit_generator.state = state["explore_rng"]
        self.env.np_random = np.random.default_rng()
        self.env.np_random.bit_generator.state = state["env_rng"]
        torch.set_rng_state(state["torch_rng"])
        self.counters = _Counters(**state["counters"])
        self.best_actor = state["best_actor"]
        start = state.get("start_gains")
        self.start_gains = None if start is None else np.asarray(start, dtype=float)

    def _actions(self, obs: np.ndarray) -> np.ndarray:
        """Raw gains: uniform in the box while warming up, else actor plus noise.

        Under a scheduled class the stiffness part of the exploration is drawn once per episode
        unless ``stiffness_exploration`` is ``"step"`` (:meth:`_hold_stiffness`).
        """
        if self.counters.step < self.config.learning_starts:
            action = self.explore.uniform(self.low, self.high, size=(len(obs), len(self.low)))
            return self._hold_stiffness(action, self.held_uniform)
        std = self.config.td3.exploration_std_at(self.counters.vector_steps)
        noise = self.explore.normal(0.0, std, size=(len(obs), len(self.low)))
        held = None if self.held_noise is None else self.held_noise * std
        return self.agent.act(obs) + self._hold_stiffness(noise, held)

    def _valued(self, asked: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action stored: the applied gains, or those asked for clipped to the box.

        Which one is ``TD3Config.critic_action``'s choice.
        """
        if self.config.td3.critic_action == "raw":
            return np.clip(asked, self.low, self.high)
        return info["applied_action"]

    def _hold_stiffness(self, action: np.ndarray, held: np.ndarray | None) -> np.ndarray:
        """``action`` with its stiffness columns replaced by the episode's draw, if any.

        A scheduled class charges every decrease of ``K_r`` to its budget (or tank) and lets
        increases pass free, so per-step noise on ``K_r`` would spend the budget within a few
        steps and then ratchet the floor up to the top of the box: the episode would explore
        nothing but the stiffest gains. Stiffness offsets held for an episode explore the
        class's free direction without spending it; the damping gains, free inside the cone,
        keep per-step noise.
        """
        if held is None:
            return action
        n = action.shape[1] // 2
        return np.concatenate([held, action[:, n:]], axis=1)

    def _draw_held(self) -> None:
        """Draw the episode's stiffness exploration (under a scheduled class, if held).

        Warm-up: the same fraction of the box on every joint; noise: the same unit normal
        offset on every joint (scaled by the current standard deviation when used).
        """
        if (self.config.stiffness_exploration == "step"
                or self.env.safety_layer.run_time_state(1).shape[1] == 0):
            return
        n = len(self.low) // 2
        fraction = self.explore.uniform(size=(self.config.num_envs, 1))
        self.held_uniform = self.low[:n] + fraction * (self.high[:n] - self.low[:n])
        self.held_noise = np.repeat(self.explore.normal(size=(self.config.num_envs, 1)), n, axis=1)

    def _learn(self, losses: list[dict[str, float]]) -> float:
        """Fix the normaliser once, then run the updates of one vector step; their seconds."""
        if self.counters.step < self.config.learning_starts:
            return 0.0
        started = time.perf_counter()
        if not self.counters.normalised:
            filled = self.buffer.obs[:len(self.buffer)]
            self.agent.set_normalizer(filled.mean(axis=0), filled.std(axis=0))
            self.counters.normalised = True
        for _ in range(self.config.updates_per_step):
            losses.append(self.agent.update(self.buffer.sample(self.config.td3.batch_size)))
        return time.perf_counter() - started

    def run_round(self, on_step: Callable[[int], None]) -> None:
        """One episode of every sub-environment, learning as it goes, then a log row."""
        start = time.perf_counter()
        counters = self.counters
        unsafe, env_seconds = self.env.unsafe_actions, self.env.seconds
        updating = 0.0
        first = counters.rounds == 0
        obs, _ = self.env.reset(seed=self.env_seed if first else None)
        self._draw_held()
        returns = np.zeros(self.config.num_envs)
        losses: list[dict[str, float]] = []
        done = False
        while not done:
            asked = self._actions(obs)
            next_obs, reward, terminated, truncated, info = self.env.step(asked)
            done = bool(terminated.any() or truncated.any())
            for transitions in self.window.push(obs, self._valued(asked, info), reward,
                                                next_obs, terminated, done):
                self.buffer.add(*transitions)
            returns += reward
            counters.step += self.config.num_envs
            counters.vector_steps += 1
            updating += self._learn(losses)
            obs = next_obs
            on_step(self.config.num_envs)
        counters.rounds += 1
        counters.unsafe_actions += self.env.unsafe_actions - unsafe
        validating = time.perf_counter()
        validation = self._validate()
        now = time.perf_counter()
        counters.wall_time += now - start
        split = {f"{part}_time": seconds - env_seconds[part]
                 for part, seconds in self.env.seconds.items()}
        split.update(update_time=updating, validation_time=now - validating)
        counters.log.append({**self._log_row(returns, losses, validation), **split})

    def _validate(self) -> float:
        """Validation cost of the deterministic actor; keep the actor if it is the best."""
        if self.config.validation_scenarios == 0:
            return math.nan
        from teleopkit.rl.evaluation import rollout

        periods = self.env.config.decision_period
        actor = self.agent.policy()
        controller = actor if periods == 1 else HeldController(actor, periods)
        run = rollout(controller, self.config.validation_scenarios, self.config.validation_seed,
                      self.validation_config)
        cost = float(run.metrics()["cost"].mean())
        self.counters.unsafe_actions += run.unsafe_actions
        if cost < self.counters.best_validation:
            self.counters.best_validation = cost
            self.counters.best_round = self.counters.rounds
            self.best_actor = {k: v.clone() for k, v in self.agent.actor.state_dict().items()}
        return cost

    def _log_row(self, returns: np.ndarray, losses: list[dict[str, float]],
                 validation: float) -> dict[str, float]:
        def mean(key: str) -> float:
            values = [x[key] for x in losses if not math.isnan(x[key])]
            return float(np.mean(values)) if values else math.nan

        counters = self.counters
        return {"step": counters.step, "round": counters.rounds,
                "episode_return": float(returns.mean()), "critic_loss": mean("critic_loss"),
                "actor_loss": mean("actor_loss"),
                "exploration_std": self.config.td3.exploration_std_at(counters.vector_steps),
                "validation_cost": validation, "wall_time": counters.wall_time,
                "unsafe_actions": counters.unsafe_actions}

    def _metadata(self) -> dict[str, Any]:
        """Training settings, the certificate (evaluation reads it) and the setup trained on."""
        start = {} if self.start_gains is None else {"start_gains": self.start_gains.tolist()}
        return {"train_config": self.config.to_dict(), "rounds": self.counters.rounds, **start,
                "gain_variation": self.env.certificate.gain_variation,
                "certificate": self.env.certificate.to_dict(),
                "setup": self.env.config.setup.record,
                "observation": self.env.config.observation,
                "decision_period": self.env.config.decision_period}

    def policy(self) -> GainPolicy:
        """The current actor with the training settings as metadata."""
        return self.agent.policy(self._metadata())

    def best_policy(self) -> GainPolicy | None:
        """The best actor by validation cost (None before the first validation)."""
        if self.best_actor is None:
            return None
        actor = copy.deepcopy(self.agent.actor)
        actor.load_state_dict(self.best_actor)
        metadata = {**self._metadata(), "rounds": self.counters.best_round,
                    "validation_cost": self.counters.best_validation}
        return GainPolicy.from_actor(actor, metadata)

    def log_frame(self) -> pd.DataFrame:
        """The log as a table."""
        columns = ["step", "round", "episode_return", "critic_loss", "actor_loss",
                   "exploration_std", "validation_cost", "wall_time", "unsafe_actions",
                   "simulation_time", "projection_time", "update_time", "validation_time"]
        return pd.DataFrame(self.counters.log, columns=columns)


def _at_defaults(recorded: dict[str, Any]) -> dict[str, Any]:
    """A settings fingerprint with the settings it predates at their defaults.

    A setting added to :class:`TrainConfig` or :class:`~teleopkit.rl.td3.TD3Config` after a
    checkpoint was written is missing from its fingerprint; the run had the setting's default
    (the behaviour before the setting existed), so it resumes under that value.
    """
    defaults = json.loads(json.dumps(TrainConfig().to_dict()))
    filled = {**{k: v for k, v in defaults.items() if k not in _RESULT_NEUTRAL}, **recorded}
    filled["td3"] = {**defaults["td3"], **recorded.get("td3", {})}
    return filled


def _short(value: Any) -> str:
    """A setting's value for a one-line message (long lists cut)."""
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _save(run: _Run, out_dir: Path) -> None:
    """Checkpoint, log and policy, each atomically (checkpoint last)."""
    atomic_write(out_dir / LOG, lambda p: run.log_frame().to_csv(p, index=False))
    atomic_write(out_dir / POLICY, lambda p: run.policy().save(p))
    best = run.best_policy()
    if best is not None:
        atomic_write(out_dir / BEST_POLICY, best.save)
    atomic_write(out_dir / CHECKPOINT, lambda p: torch.save(run.state_dict(), p))


def _prepare(run: _Run, directory: Path, resume: bool) -> None:
    """Load the checkpoint of a resumed run (refuse one without resume); record the settings."""
    checkpoint = directory / CHECKPOINT
    if checkpoint.exists() and not resume:
        raise ValueError(f"{checkpoint} exists; pass resume=True (--resume) to continue it "
                         "or choose another directory")
    if checkpoint.exists():
        run.load_state_dict(load_checkpoint(checkpoint))
    config_text = json.dumps(run.config.to_dict(), indent=2)
    atomic_write(directory / CONFIG, lambda p: p.write_text(config_text))
    certificate_text = run.env.certificate.to_json()
    atomic_write(directory / CERTIFICATE, lambda p: p.write_text(certificate_text))


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """Read a checkpoint written by :func:`train` (tensors and plain data only).

    Parameters
    ----------
    path : str or Path
        ``checkpoint.pt``.

    Returns
    -------
    dict
        Agent, buffer, generator states, counters and the settings fingerprint.
    """
    return torch.load(path, weights_only=True)


def train(config: TrainConfig, out_dir: str | Path | None = None, resume: bool = False,
          env_config: FlexTeleopConfig | None = None, progress: bool = True,
          on_round: Callable[[int], None] | None = None) -> TrainResult:
    """Train a TD3 gain tuner.

    Parameters
    ----------
    config : TrainConfig
        Settings.
    out_dir : str or Path, optional
        Directory for checkpoint, log, policy and configuration (created if needed). Without
        it nothing is written.
    resume : bool
        Continue from ``out_dir/checkpoint.pt`` if it exists (same settings required; only
        ``total_steps`` and ``checkpoint_every`` may change). Without ``resume`` an existing
        checkpoint is an error, so that runs are never mixed by accident.
    env_config : FlexTeleopConfig, optional
        Environment settings (its ``episode_length`` is replaced by the config's).
    progress : bool
        Show a tqdm progress bar (on standard error).
    on_round : callable, optional
        Called with the number of completed rounds after each round (and its checkpoint).

    Returns
    -------
    TrainResult
        Agent, log and policy.

    Raises
    ------
    ValueError
        On an existing checkpoint without ``resume``, or a checkpoint of other settings (the
        message names them).
    RunLocked
        If another live run uses ``out_dir`` (:func:`~teleopkit.files.run_lock`).
    """
    from tqdm import tqdm

    directory = Path(out_dir) if out_dir is not None else None
    resuming = resume and directory is not None and (directory / CHECKPOINT).exists()
    run = _Run(config, env_config, search_start=not resuming, progress=progress)
    with contextlib.ExitStack() as held:
        if directory is not None:
            directory.mkdir(parents=True, exist_ok=True)
            held.enter_context(run_lock(directory / LOCK, str(directory)))
            _prepare(run, directory, resume)
        per_round = config.num_envs * run.env.config.max_steps
        rounded = math.ceil(config.total_steps / per_round) * per_round
        with tqdm(total=rounded, initial=min(run.counters.step, rounded), disable=not progress,
                  unit="step", dynamic_ncols=True) as bar:
            while run.counters.step < config.total_steps:
                run.run_round(bar.update)
                last = run.counters.step >= config.total_steps
                if directory is not None and (
                        last or run.counters.rounds % config.checkpoint_every == 0):
                    _save(run, directory)
                if on_round is not None:
                    on_round(run.counters.rounds)
                row = run.counters.log[-1]
                bar.set_postfix(ret=f"{row['episode_return']:.4g}",
                                std=f"{row['exploration_std']:.3g}")
    return TrainResult(run.agent, run.log_frame(), run.policy(), run.best_policy())
