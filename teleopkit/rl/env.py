"""Gymnasium environments for certified-safe tuning of the remote gains.

:class:`FlexTeleopEnv` (registered as ``teleopkit/FlexTeleop-v0``) is one teleoperator;
:class:`FlexTeleopVectorEnv` runs ``B`` of them in one batched :class:`~teleopkit.Simulator` with
one batched safety projection, for fast experience collection.

Per control period (10 ms by default) the agent proposes remote gains
``a = [K_r^1..K_r^n, B_r^1..B_r^n]``; every action passes through the
:class:`~teleopkit.safety.SafetyLayer` of the environment's certificate before it reaches the
simulator (:class:`~teleopkit.safety.CertifiedLoop`), and the environment counts applied actions
outside the certified set (:attr:`FlexTeleopEnv.unsafe_actions`, which must stay 0).

Observation (``7 n`` values, :func:`~teleopkit.rl.scoring.observation`: the paper's Section III
with the damping error written ``theta_r - q_r``; the paper's eq. 6 has a typo) at the end of
each period::

    [theta_r, theta_r', q_l(t - T_l), e_track, int e_track, e_damp, int e_damp]

with ``e_track = theta_r - q_l(t - T_l)`` and ``e_damp = theta_r - q_r``. At ``t = 0`` the delayed
signal is the constant past ``q_l(0)``. Under a scheduled certificate (``scheduled:L`` or
``tank``) the safety layer keeps a budget or a tank, whose level is appended (``7 n + 1`` values)
and reported in ``info["schedule"]``: the set of each step depends on it.

Each episode draws its scenarios from the environment's setup (:class:`~teleopkit.setup.Setup`;
the paper's by default: operator reference gains and delay scales) with the environment's seeded
generator: operator motions, delays of each direction and starts. The time limit is a
truncation; a non-finite state or one leaving ``state_bound`` terminates with ``-failure_penalty``
(which should never happen with certified gains).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.model.params import TeleoperatorParams
from teleopkit.rl.features import AdaptiveObservation, observation_size
from teleopkit.rl.registration import ENV_ID
from teleopkit.rl.scoring import RewardWeights, observation, score
from teleopkit.safety.factory import layer_for
from teleopkit.safety.layer import SafetyLayer
from teleopkit.safety.loop import CertifiedLoop
from teleopkit.setup import Setup
from teleopkit.sim.motions import check_motion_ends
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.state import StateLayout
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT
from teleopkit.sim.timing import periods as whole_periods
from teleopkit.sim.trajectory import StepResult

__all__ = [
    "COVERING_CLASS",
    "ENV_ID",
    "BatchStep",
    "FlexTeleopConfig",
    "FlexTeleopEnv",
    "FlexTeleopVectorEnv",
    "TeleopBatch",
]


COVERING_CLASS = "tank:3"
"""The gain class tuners are trained and searched under by default (``teleopkit train``,
``teleopkit search-law``): its certificate covers every schedule a tuner plays
(``examples/train_covered.py`` measures the TD3 recipe)."""


@dataclass(frozen=True)
class FlexTeleopConfig:
    """Settings shared by :class:`FlexTeleopEnv` and :class:`FlexTeleopVectorEnv`.

    Parameters
    ----------
    setup : Setup
        Plant, network, operator motions and starts the episodes draw from (the paper's by
        default).
    certificate : GainCertificate, optional
        Certificate whose polytope the safety layer projects onto; it must be for the setup's
        plant and cover its delays. Default: :func:`default_certificate` of the plant (closed
        form) for the network's delay bounds.
    episode_length : float
        Episode duration in seconds (truncation), a whole number of control periods; a recorded
        operator motion or delay trace of the setup must last that long
        (:func:`~teleopkit.sim.motions.check_motion_ends`,
        :func:`~teleopkit.delays.spec.check_trace_ends`).
    control_period : float
        Gain hold period (agent sample time) in seconds.
    dt : float
        Integration step in seconds.
    weights : RewardWeights
        Reward weights.
    state_bound : float
        Largest admissible absolute value of a position, velocity or integrated error before
        termination (the energy integrals a storage function needs grow on every run and are
        only checked to be finite: :attr:`~teleopkit.sim.state.StateLayout.bounded`).
    decision_period : int
        Control periods per agent decision: the agent's gains are held (and projected every
        period) over that many periods, and its reward is their sum. A tuner trained with
        ``k > 1`` plays through :class:`~teleopkit.rl.controllers.HeldController` in evaluation,
        so that every row's cost is summed over the same 10 ms periods.
    observation : {"paper", "adaptive"}
        What the agent observes: the paper's ``7 n`` values, or
        :class:`~teleopkit.rl.features.AdaptiveObservation` (``11 n + 1``: link velocity,
        deflection rate, levels of motion and errors, the measured delay; no integrals).
    failure_penalty : float
        Reward ``-failure_penalty`` on termination: an order of magnitude beyond the discounted
        return of a whole episode at discount 0.99 (about -3000 under ``K_r = 10, B_r = 30``,
        mostly the opening transient; -7500 at the stiffest corner ``K_r = 50, B_r = 150``), so
        ending an episode never pays.
    """

    setup: Setup = field(default_factory=Setup.paper)
    certificate: GainCertificate | None = None
    episode_length: float = 40.0
    control_period: float = CONTROL_PERIOD
    dt: float = DEFAULT_DT
    weights: RewardWeights = field(default_factory=RewardWeights)
    state_bound: float = 1e3
    failure_penalty: float = 1e5
    observation: str = "paper"
    decision_period: int = 1

    def __post_init__(self) -> None:
        for name in ("episode_length", "control_period", "dt", "state_bound", "failure_penalty"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive and finite, got {value}")
        periods = whole_periods(self.episode_length, self.control_period)
        observation_size(self.observation, 1)  # refuses an unknown kind
        if self.decision_period < 1 or periods % self.decision_period:
            raise ValueError(f"decision_period must be a whole number >= 1 of control periods "
                             f"that divides the episode's {periods}, got {self.decision_period}")
        self.setup.operator.motion.check_ends(self.episode_length)  # recordings long enough
        self.setup.network.check_ends(self.episode_length)

    @property
    def max_steps(self) -> int:
        """Agent decisions per episode (control periods divided by ``decision_period``)."""
        return round(self.episode_length / self.control_period) // self.decision_period

    @property
    def params(self) -> TeleoperatorParams:
        """The setup's teleoperator."""
        return self.setup.params

    def safety_certificate(self) -> GainCertificate:
        """The certificate the safety layer projects onto.

        Returns
        -------
        GainCertificate
            ``certificate``, or the closed form's on the default box for the setup's plants and
            the delays its network reaches.
        """
        if self.certificate is not None:
            return self.certificate
        return default_certificate(self.params, self.setup.network.reached_bounds,
                                   plants=self.setup.plants, ranges=self.setup.ranges)


def _config(config: FlexTeleopConfig | None, overrides: dict[str, Any]) -> FlexTeleopConfig:
    """``config`` (default settings if None) with the given fields replaced."""
    return replace(config if config is not None else FlexTeleopConfig(), **overrides)


class BatchStep(NamedTuple):
    """One control period of a :class:`TeleopBatch`.

    Attributes
    ----------
    obs : ndarray, shape (B, 7 n)
        Observations at the end of the period.
    reward : ndarray, shape (B,)
        Rewards (``-failure_penalty`` where a run failed).
    terminated : ndarray of bool, shape (B,)
        Runs whose state became non-finite or left ``state_bound``.
    truncated : ndarray of bool, shape (B,)
        Runs that reached the episode length.
    info : dict of str to ndarray
        Projection report (see :class:`FlexTeleopEnv`).
    result : StepResult
        The simulated period.
    """

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, np.ndarray]
    result: StepResult


class TeleopBatch:
    """Safety projection, simulation, observation and reward for a batch of ``B`` scenarios.

    The core of both environments and of closed-loop evaluation; all of its arrays carry the
    batch axis first.

    Parameters
    ----------
    config : FlexTeleopConfig
        Settings (the certificate defaults to the closed form's for ``config.params``).
    batch : int
        Number of scenarios.
    """

    def __init__(self, config: FlexTeleopConfig, batch: int) -> None:
        self.config = config
        self.batch = batch
        network = config.setup.network
        self.certificate = config.safety_certificate()
        self.certificate.check(config.setup.plants, *network.reached_bounds,
                               network.reached_floors)
        self.loop = CertifiedLoop(layer_for(self.certificate, config.control_period))
        self.run_time_columns = self.layer.run_time_state(1).shape[1]
        self.features = (AdaptiveObservation(config.params.n_joints, config.control_period)
                         if config.observation == "adaptive" else None)
        self.steps = 0

    @property
    def layer(self) -> SafetyLayer:
        """The safety layer every action passes through."""
        return self.loop.layer

    @property
    def unsafe_actions(self) -> int:
        """Applied actions outside the certified set so far (must stay 0)."""
        return self.loop.unsafe_actions

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """Start on ``B`` scenarios drawn from the setup; first observations.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the operator motions, delays and starts.

        Returns
        -------
        ndarray, shape (B, 7 n)
            Observations at ``t = 0``.
        """
        return self.start(self.config.setup.scenarios(rng, self.batch))

    def start(self, scenario: Scenario) -> np.ndarray:
        """Start an episode on ``scenario`` and return the first observations.

        Parameters
        ----------
        scenario : Scenario
            ``B`` scenarios of the configured teleoperator.

        Returns
        -------
        ndarray, shape (B, 7 n)
            Observations at ``t = 0`` (the delayed signal is the constant past ``q_l(0)``).

        Raises
        ------
        ValueError
            A batch of another size, a recorded operator motion that ends before the episode
            does (:func:`~teleopkit.sim.motions.check_motion_ends`), or a step the model cannot
            integrate stably.
        """
        if scenario.batch != self.batch:
            raise ValueError(f"scenario has {scenario.batch} runs, the batch {self.batch}")
        config = self.config
        check_motion_ends(scenario.reference_motion, config.episode_length)
        simulator = Simulator(scenario, config.dt, config.control_period)
        state = self.loop.start(simulator)
        self.steps = 0
        delayed = StateLayout.of(state).get(state, "ql")  # the constant past
        if self.features is not None:
            delay = simulator.initial_record().delays[0, :, 0]
            return self._observe(self.features.start(state, delayed, delay))
        return self._observe(observation(state, delayed))

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        """The paper's observation, then the safety layer's run-time state (if it keeps one)."""
        if not self.run_time_columns:
            return obs
        return np.concatenate([obs, self.layer.run_time_state(self.batch)], axis=1)

    def step(self, raw: np.ndarray) -> BatchStep:
        """Project, simulate and score one decision: ``decision_period`` control periods.

        The raw gains are held and projected every period; the reward is the periods' sum, the
        observation, result and info those of the last period (``applied_action`` the first's).

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n)
            Raw gains (any values, NaN and inf included).

        Returns
        -------
        BatchStep
            Observations, rewards, terminations, truncations, info and the simulated period.
        """
        raw = np.array(raw, dtype=np.float64).reshape(self.batch, -1)
        bound = self.config.state_bound
        reward = np.zeros(self.batch)
        for period in range(self.config.decision_period):
            result, projection = self.loop.step(raw)
            if period == 0:
                applied = projection.action
            obs, gained, failed, failures = score(result.state[0], result.delayed[0, :, 0],
                                                  projection.action, self.config.weights, bound)
            reward += gained
            if self.features is not None:
                obs = self.features.step(result.state[0], result.delayed[0, :, 0],
                                         result.delays[0, :, 0])
            if failures:
                break
        self.steps += 1
        obs = self._observe(obs)
        if failures:
            reward[failed] = -self.config.failure_penalty
            obs = np.clip(np.nan_to_num(obs), -bound, bound)
        truncated = np.full(self.batch, self.steps >= self.config.max_steps) & ~failed
        info = {"raw_action": raw, "applied_action": applied,
                "projection_distance": projection.distance,
                "fallback": projection.fallback != 0, "fallback_flags": projection.fallback,
                "active_constraints": projection.active, "time": np.full(self.batch, result.t[0]),
                "delays": result.delays[0]}
        if self.run_time_columns:
            info["schedule"] = projection.schedule
        return BatchStep(obs, reward, failed, truncated, info, result)


def _spaces(config: FlexTeleopConfig, core: TeleopBatch) -> tuple[spaces.Box, spaces.Box]:
    """Action space (the certificate's gain box) and observation space of one scenario.

    Every observation entry is a bounded state entry (motion, integrated errors) or the
    difference of two, and the episode ends once one exceeds ``state_bound``, so observations
    lie within twice that bound; a
    scheduled class appends its budget or tank level.
    """
    box = core.certificate.box
    limit = 2 * config.state_bound
    size = observation_size(config.observation, box.n_joints) + core.run_time_columns
    action = spaces.Box(box.lower, box.upper, dtype=np.float64)
    observation = spaces.Box(-limit, limit, shape=(size,), dtype=np.float64)
    return action, observation


class FlexTeleopEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """One teleoperator whose remote gains an agent retunes every control period.

    Create it with ``gymnasium.make("teleopkit/FlexTeleop-v0", episode_length=2.0)`` (after
    ``import teleopkit``) or directly. Keyword arguments override fields of ``config``.

    Parameters
    ----------
    config : FlexTeleopConfig, optional
        Settings; the defaults of :class:`FlexTeleopConfig` if omitted.
    **overrides
        Fields of :class:`FlexTeleopConfig` to replace (for example ``episode_length=2.0``).

    Attributes
    ----------
    safety_layer : SafetyLayer
        Projection onto the certificate's polytope applied to every action.
    certificate : GainCertificate
        The certificate in force.

    Notes
    -----
    ``step`` returns ``info`` with ``raw_action``, ``applied_action``, ``projection_distance``,
    ``fallback`` (bool), ``fallback_flags`` (:class:`~teleopkit.safety.Fallback`),
    ``active_constraints`` (mask over the polytope's rows; labels via
    ``safety_layer.active_labels``), ``time`` and ``delays``. The previous applied action is the
    centre of a rate-bounded certificate's rate box and the fallback for non-finite actions.
    """

    def __init__(self, config: FlexTeleopConfig | None = None, **overrides: Any) -> None:
        super().__init__()
        self.config = _config(config, overrides)
        self._core = TeleopBatch(self.config, 1)
        self.safety_layer = self._core.layer
        self.certificate = self._core.certificate
        self.action_space, self.observation_space = _spaces(self.config, self._core)

    @property
    def unsafe_actions(self) -> int:
        """Applied actions outside the certified set since construction (must stay 0)."""
        return self._core.unsafe_actions

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode with a freshly drawn scenario.

        Parameters
        ----------
        seed : int, optional
            Seed of the environment's generator (scenario draws).
        options : dict, optional
            Unused.

        Returns
        -------
        observation : ndarray, shape (7 n,)
            Observation at ``t = 0``.
        info : dict
            Empty.
        """
        super().reset(seed=seed)
        return self._core.draw(self.np_random)[0], {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Project the action, simulate one control period and score it.

        Parameters
        ----------
        action : ndarray, shape (2 n,)
            Raw gains ``[K_r..., B_r...]`` (any values, NaN and inf included).

        Returns
        -------
        observation : ndarray, shape (7 n,)
            Observation at the end of the period.
        reward : float
            See :class:`RewardWeights` (``-failure_penalty`` on termination).
        terminated : bool
            The state became non-finite or left ``state_bound``.
        truncated : bool
            The episode reached ``episode_length``.
        info : dict
            Projection report (see the class notes).
        """
        obs, reward, terminated, truncated, info, _ = self._core.step(action)
        return (obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]),
                {key: value[0] for key, value in info.items()})


class FlexTeleopVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` teleoperators simulated together (one batched simulator and projection).

    All sub-environments share the clock, so their episodes start and end together: at the time
    limit all are truncated; if one terminates (a failure, which should never happen with
    certified gains) the others are truncated at the same step. Autoreset follows Gymnasium's
    next-step mode: the step after the end ignores the actions and returns the first
    observations of new scenarios with zero reward.

    Parameters
    ----------
    num_envs : int
        Number of scenarios ``B``.
    config : FlexTeleopConfig, optional
        Settings; the defaults of :class:`FlexTeleopConfig` if omitted.
    **overrides
        Fields of :class:`FlexTeleopConfig` to replace.

    Attributes
    ----------
    safety_layer : SafetyLayer
        Projection onto the certificate's polytope applied to every action.
    certificate : GainCertificate
        The certificate in force.
    """

    def __init__(self, num_envs: int = 8, config: FlexTeleopConfig | None = None,
                 **overrides: Any) -> None:
        if num_envs < 1:
            raise ValueError(f"num_envs must be at least 1, got {num_envs}")
        self.metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
        self.num_envs = num_envs
        self.config = _config(config, overrides)
        self._core = TeleopBatch(self.config, num_envs)
        self.safety_layer = self._core.layer
        self.certificate = self._core.certificate
        single_action, single_observation = _spaces(self.config, self._core)
        self.single_action_space, self.single_observation_space = single_action, single_observation
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self._ended = False

    @property
    def unsafe_actions(self) -> int:
        """Applied actions outside the certified set since construction (must stay 0)."""
        return self._core.unsafe_actions

    @property
    def seconds(self) -> dict[str, float]:
        """Wall time of the safety projection and of the simulation since construction.

        The ``seconds`` of the batch's :class:`~teleopkit.safety.CertifiedLoop`.
        """
        return dict(self._core.loop.seconds)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start new episodes in every sub-environment.

        Parameters
        ----------
        seed : int, optional
            Seed of the generator that draws all scenarios.
        options : dict, optional
            Unused.

        Returns
        -------
        observations : ndarray, shape (num_envs, 7 n)
            Observations at ``t = 0``.
        info : dict
            Empty.
        """
        super().reset(seed=seed)
        self._ended = False
        return self._core.draw(self.np_random), {}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                 dict[str, Any]]:
        """Step every sub-environment (or autoreset them all after the episodes ended).

        Parameters
        ----------
        actions : ndarray, shape (num_envs, 2 n)
            Raw gains of each sub-environment.

        Returns
        -------
        observations : ndarray, shape (num_envs, 7 n)
            Observations.
        rewards : ndarray, shape (num_envs,)
            Rewards (0 on an autoreset step).
        terminations : ndarray of bool, shape (num_envs,)
            Failures.
        truncations : ndarray of bool, shape (num_envs,)
            Episode ends by time limit (or by another sub-environment's failure).
        info : dict
            Batched projection report (see :class:`FlexTeleopEnv`), each key with its ``_key``
            mask; empty on an autoreset step.
        """
        if self._ended:
            self._ended = False
            none = np.zeros(self.num_envs, dtype=bool)
            return self._core.draw(self.np_random), np.zeros(self.num_envs), none, none, {}
        obs, reward, terminated, truncated, info, _ = self._core.step(actions)
        if terminated.any() or truncated.any():
            truncated = ~terminated
            self._ended = True
        masks = {f"_{key}": np.ones(self.num_envs, dtype=bool) for key in info}
        return obs, reward, terminated, truncated, {**info, **masks}
