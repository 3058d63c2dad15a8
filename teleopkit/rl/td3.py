r"""TD3 gain tuner (Fujimoto, van Hoof & Meger 2018) for the certified-safe teleoperation env.

Read top to bottom, like CleanRL's ``td3_continuous_action.py``, but as a small library:

1. :class:`TD3Config`, the hyperparameters (the paper's and the authors' settings);
2. :class:`~teleopkit.rl.networks.Actor` and :class:`~teleopkit.rl.networks.Critic`, the
   paper's networks;
3. :class:`~teleopkit.rl.torch_projection.TorchProjection`, the safety layer's projection written
   in torch so that the actor is trained *through* it;
4. :class:`~teleopkit.rl.replay.ReplayBuffer`, preallocated numpy storage with seeded sampling;
5. :class:`TD3`, the learner: twin critics, target networks, delayed actor updates, target policy
   smoothing, soft target updates;
6. :class:`~teleopkit.rl.policy.GainPolicy`, the trained actor as plain numpy for deployment (no
   torch in the loop).

How actions flow
----------------
The actor outputs *raw* gains ``a_raw = [K_r..., B_r...]`` in gain units. Its last layer is a
softplus, scaled and offset per coordinate so that its range covers the action box
``[low, high]`` (the certificate's gain box)::

    a_raw = low + (start - low) * softplus(z) / ln 2

so ``z = 0`` gives ``start`` (the centre of the box unless ``TD3Config.start`` says
otherwise), ``z -> -inf`` the lower corner, and large ``z`` values above the upper corner (every
point of the box is reached; the projection takes care of the rest). With
``TD3Config(output_map="tanh")`` the map is ``low + (high - low) (1 + tanh(z)) / 2`` instead:
the box and nothing beyond it.
The environment projects ``a_raw`` (plus exploration noise) onto the certified polytope and the
replay buffer stores the *applied* action, so the critics learn ``Q(s, a)`` on certified actions
only. The actor is trained through the projection: its loss is

    -Q_1(s, P(pi(s))) + lambda * ||(pi(s) - P(pi(s))) / half_range||^2,

with ``P`` the exact Euclidean projection onto the polytope in torch (:class:`TorchProjection`,
piecewise affine, so autograd gives its exact Jacobian: identity inside the set, the tangent
projector on an edge, zero at a vertex). The Q term moves the applied action along the set's
boundary; the penalty (``projection_penalty``) pulls raw actions back towards the set, where the Q
term alone gives no gradient in the normal direction, so raw outputs cannot drift away unseen.
Target policy smoothing adds clipped noise to the target actor's raw action and projects the
result too. A rate bound of a rate-certified layer is enforced by the environment but is not
part of this projection (the critic still sees the applied, rate-limited action). With
``TD3Config(critic_action="raw")`` the critics value the raw gains instead (clipped to the box)
and the projection stays in the environment, as for a trainer that does not know the set; the
environment projects every applied gain either way.

Inputs of both networks are standardised with fixed statistics (:meth:`TD3.set_normalizer`, set
once from the first collected transitions): the entries' spreads differ by three orders of
magnitude (standard deviation 2e-4 rad s for the integrated damping error, 0.3 rad s for the
integrated tracking error, under random gains).
Critics see the action rescaled to ``[-1, 1]`` over the box.

All randomness goes through generators owned by the objects (a ``torch.Generator`` for weight
initialisation and target smoothing, a numpy ``Generator`` for the replay buffer), never through
the global RNGs, and is part of the state dicts.

Threads: a batch-512 update takes about 5 ms on one core (about 200 updates/s; a second,
otherwise idle core adds 6 %: ``benchmarks/bench_agent.py``). Training also steps the
simulator, which needs the second core on a 2-core machine, so the command line and the
examples call ``torch.set_num_threads(1)``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.rl.networks import Actor, Critic, Standardise, half_range
from teleopkit.rl.policy import GainPolicy, check_output_map
from teleopkit.rl.replay import Batch
from teleopkit.rl.torch_projection import torch_projection
from teleopkit.safety.layer import SafetyLayer

__all__ = ["TD3", "TD3Config"]

_M = TypeVar("_M", bound=nn.Module)


@dataclass(frozen=True)
class TD3Config:
    """Hyperparameters of :class:`TD3` (defaults: the paper's and the authors' settings).

    Parameters
    ----------
    discount : float
        Discount factor.
    batch_size : int
        Minibatch size of each gradient update.
    actor_lr, critic_lr : float
        Adam learning rates.
    grad_clip : float
        Largest total gradient norm of each network per update.
    tau : float
        Soft target update coefficient: ``target <- (1 - tau) target + tau online``.
    policy_delay : int
        Critic updates per actor (and target) update.
    exploration_std : float
        Initial standard deviation of the Gaussian exploration noise, in gain units.
    exploration_std_min : float
        Floor of the exploration standard deviation.
    exploration_decay : float
        Exponential decay rate per environment step: ``std_k = max(min, std_0 (1 - rate)^k)``.
    target_noise : float
        Standard deviation of the target policy smoothing noise, as a fraction of half the box
        range of each gain (Fujimoto et al.'s 0.2 for actions in ``[-1, 1]``).
    target_noise_clip : float
        Clip of the smoothing noise, same units.
    reward_scale : float
        Factor applied to rewards in the critic targets (the reward itself is unchanged). Not a
        paper setting: 0.01 keeps the Q-values of the environment's default reward weights
        between about -40 (opening transient) and -1; unscaled, the short test problem of
        ``tests/rl/test_rl_training.py`` does not learn at all in 2 000 updates.
    projection_penalty : float
        Weight ``lambda`` of the actor's squared distance to the set (normalised units).
    hidden_actor : tuple of int
        Hidden widths of the actor.
    hidden_state, hidden_action, hidden_merged : tuple of int
        Critic: state path, action path and merged layers (before the scalar output); an
        empty ``hidden_action`` joins the paths (observation and action at one input).
    start : tuple of float, optional
        Gains the untrained actor outputs (:class:`~teleopkit.rl.networks.Actor`); default the
        centre of the box. Starting from the best static gains of the certified set makes
        training a refinement of them (residual-style: Silver et al. 2018).
    critic_action : {"applied", "raw"}
        What the critics learn the value of. ``"applied"`` (the paper's design): the certified
        gains the safety layer applied, the actor trained through the exact projection.
        ``"raw"``: the gains the actor asked for, clipped to the box, the projection left to
        the environment as part of its dynamics (as a library trainer that knows nothing of
        the set learns, e.g. Stable-Baselines3's TD3); every applied gain is projected either
        way.
    output_map : {"softplus", "tanh"}
        The actor's output map (:data:`~teleopkit.rl.policy.OUTPUT_MAPS`): the paper's
        softplus, unbounded above, or a tanh onto the box.
    """

    discount: float = 0.99
    batch_size: int = 512
    actor_lr: float = 1e-4
    critic_lr: float = 1e-4
    grad_clip: float = 1.0
    tau: float = 0.005
    policy_delay: int = 2
    exploration_std: float = 4.0
    exploration_std_min: float = 0.05
    exploration_decay: float = 1e-7
    target_noise: float = 0.2
    target_noise_clip: float = 0.5
    reward_scale: float = 0.01
    projection_penalty: float = 1.0
    hidden_actor: tuple[int, ...] = (128, 64)
    hidden_state: tuple[int, ...] = (128, 64)
    hidden_action: tuple[int, ...] = (64,)
    hidden_merged: tuple[int, ...] = (60, 36)
    start: tuple[float, ...] | None = None
    critic_action: str = "applied"
    output_map: str = "softplus"

    def __post_init__(self) -> None:
        check_output_map(self.output_map, "output_map")
        if self.critic_action not in ("applied", "raw"):
            raise ValueError("critic_action must be 'applied' or 'raw', got "
                             f"{self.critic_action!r}")
        if not 0 <= self.discount <= 1:
            raise ValueError(f"discount must be in [0, 1], got {self.discount}")
        if not 0 < self.tau <= 1:
            raise ValueError(f"tau must be in (0, 1], got {self.tau}")
        for name in ("batch_size", "policy_delay"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        for name in ("actor_lr", "critic_lr", "grad_clip", "reward_scale"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0 <= self.exploration_std_min <= self.exploration_std:
            raise ValueError("need 0 <= exploration_std_min <= exploration_std")
        if not 0 <= self.exploration_decay < 1:
            raise ValueError(f"exploration_decay must be in [0, 1), got {self.exploration_decay}")

    def exploration_std_at(self, step: int) -> float:
        """Exploration standard deviation after ``step`` environment steps.

        Parameters
        ----------
        step : int
            Environment steps taken so far.

        Returns
        -------
        float
            ``max(std_min, std (1 - decay)^step)``.
        """
        decayed = self.exploration_std * (1.0 - self.exploration_decay) ** step
        return max(self.exploration_std_min, decayed)


def _soft_update(target: list[torch.Tensor], online: list[torch.Tensor], tau: float) -> None:
    """``target <- (1 - tau) target + tau online`` for every parameter."""
    with torch.no_grad():
        torch._foreach_lerp_(target, online, tau)


def _requires_grad(params: list[torch.Tensor], flag: bool) -> None:
    """Switch the gradients of ``params`` on or off."""
    for param in params:
        param.requires_grad_(flag)


def _copy(module: _M) -> _M:
    """A frozen deep copy (target network)."""
    clone = copy.deepcopy(module)
    clone.requires_grad_(False)
    return clone


class TD3:
    """Twin Delayed DDPG on the certified action set.

    Parameters
    ----------
    obs_dim : int
        Observation size.
    low, high : ndarray, shape (act_dim,)
        Action box (the environment's action space).
    certified : GainPolytope, ScheduledSet or SafetyLayer
        Certified set the environment projects onto (a safety layer stands for its
        :attr:`~teleopkit.safety.layer.SafetyLayer.admissible_set`).
    config : TD3Config, optional
        Hyperparameters.
    seed : int
        Seed of the initial weights and of the target smoothing noise.

    Examples
    --------
    >>> from teleopkit.rl.env import FlexTeleopVectorEnv
    >>> env = FlexTeleopVectorEnv(2, episode_length=0.05)
    >>> agent = TD3.for_env(env, seed=0)
    >>> obs, _ = env.reset(seed=0)
    >>> agent.act(obs).shape
    (2, 4)
    """

    def __init__(self, obs_dim: int, low: np.ndarray, high: np.ndarray,
                 certified: GainPolytope | ScheduledSet | SafetyLayer,
                 config: TD3Config | None = None, seed: int = 0) -> None:
        self.config = config if config is not None else TD3Config()
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        self.generator = torch.Generator().manual_seed(seed)
        cfg = self.config
        self.actor = Actor(obs_dim, low, high, self.generator, cfg.hidden_actor,
                           None if cfg.start is None else np.asarray(cfg.start), cfg.output_map)
        self.critics = nn.ModuleList(Critic(obs_dim, low, high, self.generator, cfg.hidden_state,
                                            cfg.hidden_action, cfg.hidden_merged)
                                     for _ in range(2))
        self.actor_target = _copy(self.actor)
        self.critic_targets = _copy(self.critics)
        self.projection = torch_projection(certified)
        # The fused CPU kernel: same arithmetic as the default, a quarter of the time here.
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=cfg.actor_lr,
                                                fused=True)
        self.critic_optimizers = [torch.optim.Adam(c.parameters(), lr=cfg.critic_lr, fused=True)
                                  for c in self.critics]
        self.half_range = torch.as_tensor(half_range(low, high), dtype=torch.float32)
        self.box = (torch.as_tensor(low, dtype=torch.float32),
                    torch.as_tensor(high, dtype=torch.float32))
        self.updates = 0
        # Parameter lists taken once: walking the modules at every clip, soft update and critic
        # freeze cost about 0.1 ms per update.
        self._params: dict[str, list[torch.Tensor]] = {
            name: list(module.parameters()) for name, module in self._networks().items()}
        self._critic_params: list[list[torch.Tensor]] = [list(c.parameters())
                                                         for c in self.critics]

    @classmethod
    def for_env(cls, env: Any, config: TD3Config | None = None, seed: int = 0) -> TD3:
        """An agent sized for a :class:`~teleopkit.rl.env.FlexTeleopVectorEnv` (or single env).

        Parameters
        ----------
        env : FlexTeleopEnv or FlexTeleopVectorEnv
            Environment whose spaces and safety layer the agent uses.
        config : TD3Config, optional
            Hyperparameters (the defaults when omitted).
        seed : int
            Seed of the networks' initialisation, exploration and replay sampling.

        Returns
        -------
        TD3
            The agent.
        """
        space = getattr(env, "single_action_space", env.action_space)
        observation = getattr(env, "single_observation_space", env.observation_space)
        return cls(observation.shape[0], space.low, space.high,
                   env.safety_layer.admissible_set, config, seed)

    def _networks(self) -> dict[str, nn.Module]:
        return {"actor": self.actor, "critics": self.critics, "actor_target": self.actor_target,
                "critic_targets": self.critic_targets}

    def set_normalizer(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Fix the observation standardisation of every network (online and target).

        Parameters
        ----------
        mean, std : ndarray, shape (obs_dim,)
            Statistics of collected observations; entries of ``std`` are floored at
            ``1e-6 (1 + |mean|)`` so that constant inputs stay finite.
        """
        mean = np.asarray(mean, dtype=float)
        std = np.maximum(np.asarray(std, dtype=float), 1e-6 * (1 + np.abs(mean)))
        for module in self._networks().values():
            for sub in module.modules():
                if isinstance(sub, Standardise):
                    sub.mean.copy_(torch.as_tensor(mean))
                    sub.std.copy_(torch.as_tensor(std))

    def act(self, obs: np.ndarray, std: float = 0.0,
            rng: np.random.Generator | None = None) -> np.ndarray:
        """Raw gains for a batch of observations, with Gaussian exploration noise if ``std > 0``.

        Parameters
        ----------
        obs : ndarray, shape (B, obs_dim)
            Observations.
        std : float
            Exploration standard deviation in gain units.
        rng : numpy.random.Generator, optional
            Noise source (required when ``std > 0``).

        Returns
        -------
        ndarray, shape (B, act_dim)
            Raw actions (the environment projects them).
        """
        with torch.no_grad():
            action = self.actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()
        action = action.astype(np.float64)
        if std > 0:
            if rng is None:
                raise ValueError("exploration noise needs a generator")
            action = action + rng.normal(0.0, std, size=action.shape)
        return action

    def update(self, batch: Batch) -> dict[str, float]:
        """One TD3 step: both critics, and every ``policy_delay`` steps the actor and targets.

        Parameters
        ----------
        batch : Batch
            Transitions with applied (certified) actions.

        Returns
        -------
        dict
            ``critic_loss`` (mean of the twins) and ``actor_loss`` (NaN when the actor was not
            updated).
        """
        cfg = self.config
        target = self._critic_target(batch)
        losses = [F.mse_loss(critic(batch.obs, batch.action), target) for critic in self.critics]
        # the twins share no weights: one backward pass of the summed losses gives each its own
        self._step(list(zip(self.critic_optimizers, self._critic_params, strict=True)),
                   torch.stack(losses).sum())
        self.updates += 1
        actor_loss = math.nan
        if self.updates % cfg.policy_delay == 0:
            actor_loss = self._update_actor(batch.obs)
            _soft_update(self._params["actor_target"], self._params["actor"], cfg.tau)
            _soft_update(self._params["critic_targets"], self._params["critics"], cfg.tau)
        return {"critic_loss": float(np.mean([loss.item() for loss in losses])),
                "actor_loss": actor_loss}

    def _critic_target(self, batch: Batch) -> torch.Tensor:
        """``R + discount^k (1 - terminated) min_i Q'_i(s', a(pi'(s') + clipped noise))``.

        ``a`` is :meth:`_valued`: the projection onto the set, or the clip to the box.

        ``R`` is the transition's discounted reward sum over its ``k`` steps (``batch.steps``;
        ``R = r`` and ``k = 1`` for a one-step transition).
        """
        cfg = self.config
        with torch.no_grad():
            raw = self.actor_target(batch.next_obs)
            noise = torch.randn(raw.shape, generator=self.generator) * cfg.target_noise
            noise = noise.clamp(-cfg.target_noise_clip, cfg.target_noise_clip) * self.half_range
            next_action = self._valued(raw + noise, batch.next_obs)
            q_next = torch.minimum(*(c(batch.next_obs, next_action) for c in self.critic_targets))
            return (cfg.reward_scale * batch.reward
                    + cfg.discount ** batch.steps * (1.0 - batch.terminated) * q_next)

    def _valued(self, raw: torch.Tensor, obs: torch.Tensor) -> torch.Tensor:
        """The action the critics value for raw gains: projected, or clipped to the box."""
        if self.config.critic_action == "raw":
            return torch.minimum(torch.maximum(raw, self.box[0]), self.box[1])
        return self.projection(raw, obs)

    def _update_actor(self, obs: torch.Tensor) -> float:
        """Gradient step on ``-Q_1(s, a(pi(s)))`` plus the distance-to-set penalty.

        ``a`` is :meth:`_valued`; the penalty, the squared distance of the raw gains to it in
        half-ranges, pulls raw gains back to the set (or the box) where the value gives no
        gradient.
        """
        raw = self.actor(obs)
        applied = self._valued(raw, obs)
        outside = ((raw - applied) / self.half_range).pow(2).sum(-1).mean()
        _requires_grad(self._critic_params[0], False)  # no gradients for the critic's weights
        loss = -self.critics[0](obs, applied).mean() + self.config.projection_penalty * outside
        self._step([(self.actor_optimizer, self._params["actor"])], loss)
        _requires_grad(self._critic_params[0], True)
        return float(loss.item())

    def _step(self, pairs: list[tuple[torch.optim.Optimizer, list[torch.Tensor]]],
              loss: torch.Tensor) -> None:
        """One backward pass of ``loss``, then each list's gradient clipped and stepped."""
        for optimizer, _ in pairs:
            optimizer.zero_grad(set_to_none=True)
        loss.backward()
        for optimizer, params in pairs:
            nn.utils.clip_grad_norm_(params, self.config.grad_clip)
            optimizer.step()

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimisers, update counter and generator state."""
        state: dict[str, Any] = {name: m.state_dict() for name, m in self._networks().items()}
        state["actor_optimizer"] = self.actor_optimizer.state_dict()
        state["critic_optimizers"] = [o.state_dict() for o in self.critic_optimizers]
        state["updates"] = self.updates
        state["generator"] = self.generator.get_state()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`state_dict` returned.

        Parameters
        ----------
        state : dict
            Output of :meth:`state_dict`.
        """
        for name, module in self._networks().items():
            module.load_state_dict(state[name])
        # Optimisers keep the loaded tensors: copy them, or two agents would share moments.
        self.actor_optimizer.load_state_dict(copy.deepcopy(state["actor_optimizer"]))
        for optimizer, saved in zip(self.critic_optimizers, state["critic_optimizers"],
                                    strict=True):
            optimizer.load_state_dict(copy.deepcopy(saved))
        self.updates = int(state["updates"])
        self.generator.set_state(state["generator"])

    def policy(self, metadata: dict[str, Any] | None = None) -> GainPolicy:
        """The current actor as a numpy :class:`GainPolicy`.

        Parameters
        ----------
        metadata : dict, optional
            JSON-ready data stored with the policy.

        Returns
        -------
        GainPolicy
            The policy.
        """
        return GainPolicy.from_actor(self.actor, metadata)
