"""Baselines without learning: the paper's gains, the best static gains, a tuned semi-active law.

The honest comparison for a gain tuner is not only the paper's fixed gains
``K_r = 10, B_r = 30`` but the best *constant* gains the same safety layer allows.
:func:`best_static_gains` finds them by minimising the paper's cost (the episode's negative
return under the environment's reward weights, :func:`static_cost`) over training scenarios: a
coarse grid of uniform gains (the same on every joint) projected onto the set, then Nelder–Mead
over all ``2 n`` gains from the best grid point. Nelder–Mead moves a free point ``x`` and the
cost is evaluated at its projection ``P(x)``, so every candidate, and the answer ``P(x*)``, lies
in the certified set.

:func:`best_semi_active` tunes the three numbers of the hand-written semi-active damping law
(:class:`~teleopkit.rl.controllers.SemiActiveDamping`) the same way, in closed loop.

Constant gains need no agent in the loop, so costs come straight from one batched
:class:`~teleopkit.sim.simulator.Simulator` run per candidate: the same numbers as stepping the
environment (see ``tests/rl/test_rl_evaluation.py``), at a fraction of the cost.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from teleopkit.progress import counting, reports_progress
from teleopkit.rl.controllers import SemiActiveDamping
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.safety.factory import layer_for
from teleopkit.safety.layer import SafetyLayer
from teleopkit.setup import Setup
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.state import StateLayout

__all__ = [
    "BASELINE_SEED",
    "FIXED_GAINS",
    "SemiActiveGains",
    "StaticGains",
    "best_semi_active",
    "best_static_gains",
    "fixed_gains",
    "static_cost",
    "uniform_gain_grid",
]

_log = logging.getLogger(__name__)

FIXED_GAINS = (10.0, 30.0)
"""The paper's fixed remote gains ``(K_r, B_r)`` on every joint."""

BASELINE_SEED = 20_251_130
"""Default seed of the training scenarios of :func:`best_static_gains`."""

RUN_BATCH = 64
"""Most scenarios :func:`static_cost` simulates at once: a 40 s run records every control period
(about 1 MB per scenario), so a whole grid of candidates in one batch would need gigabytes
(``benchmarks/bench_memory.py``)."""


def fixed_gains(kr: float = FIXED_GAINS[0], br: float = FIXED_GAINS[1],
                n_joints: int = 2) -> np.ndarray:
    """Uniform gains as an action vector ``[K_r..., B_r...]``.

    Parameters
    ----------
    kr, br : float
        Gains of every joint.
    n_joints : int
        Number of joints.

    Returns
    -------
    ndarray, shape (2 n,)
        The action.
    """
    return np.concatenate([np.full(n_joints, float(kr)), np.full(n_joints, float(br))])


def static_cost(gains: np.ndarray, scenario: Scenario,
                config: FlexTeleopConfig | None = None) -> np.ndarray:
    """The paper's cost of constant gains: minus the episode return, per candidate and scenario.

    Parameters
    ----------
    gains : ndarray, shape (C, 2 n) or (2 n,)
        Candidate gains (applied as given: project them first).
    scenario : Scenario
        ``S`` scenarios (any delays, operator motions and starts).
    config : FlexTeleopConfig, optional
        Episode length, periods, integration step and reward weights (defaults if omitted).

    Returns
    -------
    ndarray, shape (C, S)
        ``sum_k alpha ||e_track||^2 + beta ||e_damp||^2 + gamma ||a||^2`` over the episode
        (``inf`` where the state leaves the environment's ``state_bound``).
    """
    config = config if config is not None else FlexTeleopConfig(Setup.from_params(scenario.params))
    gains = np.atleast_2d(np.asarray(gains, dtype=float))
    group = max(1, RUN_BATCH // scenario.batch)  # candidates per simulated batch
    return np.concatenate([_costs(gains[start:start + group], scenario, config)
                           for start in range(0, len(gains), group)])


def _costs(gains: np.ndarray, scenario: Scenario, config: FlexTeleopConfig) -> np.ndarray:
    """:func:`static_cost` of a few candidates, simulated as one batch."""
    count, batch = gains.shape[0], scenario.batch
    sim = Simulator(scenario.repeat(count), config.dt, config.control_period)
    run = sim.run(config.max_steps * config.control_period, np.repeat(gains, batch, axis=0))
    reward = config.weights.reward(run.e_track[1:], run.e_damp[1:], run.gains[1:])
    cost = -reward.sum(axis=0)
    failed = StateLayout.of(run.state).escaped(run.state, config.state_bound)
    return np.where(failed, np.inf, cost).reshape(count, batch)


@dataclass(frozen=True)
class StaticGains:
    """Result of :func:`best_static_gains`.

    Attributes
    ----------
    gains : ndarray, shape (2 n,)
        The best certified constant gains found.
    cost : float
        Their mean cost over the training scenarios.
    grid_best : ndarray, shape (2 n,)
        Best (projected) grid point, where Nelder–Mead started.
    grid_cost : float
        Its mean cost.
    evaluations : int
        Candidates simulated (grid and Nelder–Mead).
    """

    gains: np.ndarray
    cost: float
    grid_best: np.ndarray
    grid_cost: float
    evaluations: int


def uniform_gain_grid(layer: SafetyLayer, lower: np.ndarray, upper: np.ndarray,
                      points: int) -> np.ndarray:
    """Uniform gains (one ``K_r``, one ``B_r`` on every joint) on a grid, inside the set.

    Parameters
    ----------
    layer : SafetyLayer
        Its set receives the grid (:meth:`project_set`).
    lower, upper : array_like, shape (2 n,)
        Corners of the gain box; the grid spans the first joint's ``K_r`` and ``B_r`` ranges.
    points : int
        Grid points per gain.

    Returns
    -------
    ndarray, shape (C, 2 n)
        The ``points x points`` grid projected onto the set, duplicates removed.
    """
    n = layer.dimension // 2
    k = np.linspace(lower[0], upper[0], points)
    b = np.linspace(lower[n], upper[n], points)
    kk, bb = (x.ravel() for x in np.meshgrid(k, b))
    raw = np.column_stack([np.repeat(kk[:, None], n, 1), np.repeat(bb[:, None], n, 1)])
    return np.unique(layer.project_set(raw).round(12), axis=0)


@reports_progress
def best_static_gains(layer: SafetyLayer | None = None, scenarios: int = 16,
                      seed: int = BASELINE_SEED, grid_points: int = 8, max_evaluations: int = 200,
                      config: FlexTeleopConfig | None = None,
                      progress: bool | None = None) -> StaticGains:
    """Best constant gains inside the safety layer's set for the paper's cost, for a setup.

    Parameters
    ----------
    layer : SafetyLayer, optional
        The set; the environment's default certificate if omitted.
    scenarios : int
        Training scenarios, drawn from the setup of ``config`` with ``seed``.
    seed : int
        Seed of the training scenarios (keep it apart from evaluation seeds).
    grid_points : int
        Grid resolution per gain (uniform gains on every joint).
    max_evaluations : int
        Budget of Nelder–Mead cost evaluations.
    config : FlexTeleopConfig, optional
        Environment settings (episode length, reward weights, ...).
    progress : bool, optional
        Show the search on standard error: by default on a terminal only; ``False`` never,
        ``True`` always (:mod:`teleopkit.progress`).

    Returns
    -------
    StaticGains
        Gains, cost, grid optimum and number of simulated candidates.
    """
    from scipy.optimize import minimize  # deferred: a 0.7 s import

    config = config if config is not None else FlexTeleopConfig()
    certificate = config.safety_certificate()
    if layer is None:
        layer = layer_for(certificate, config.control_period)
    box = certificate.box
    scenario = config.setup.scenarios(seed, scenarios)
    candidates = uniform_gain_grid(layer, box.lower, box.upper, grid_points)
    _log.info("best static gains: simulating %d grid candidates", len(candidates))
    grid_costs = static_cost(candidates, scenario, config).mean(axis=1)
    start = candidates[int(np.argmin(grid_costs))]

    @counting(_log, "best static gains", max_evaluations)
    def objective(x: np.ndarray) -> float:
        value = static_cost(layer.project_set(x), scenario, config).mean()
        return float(value) if math.isfinite(value) else 1e300

    result = minimize(objective, start, method="Nelder-Mead",
                      options={"maxfev": max_evaluations, "xatol": 1e-2, "fatol": 1e-3,
                               "initial_simplex": _simplex(start)})
    gains = layer.project_set(result.x)
    cost = float(result.fun)
    if cost > grid_costs.min():  # never worse than the grid
        gains, cost = start, float(grid_costs.min())
    return StaticGains(gains, cost, start, float(grid_costs.min()),
                       len(candidates) + int(result.nfev))


def _simplex(start: np.ndarray) -> np.ndarray:
    """Initial Nelder–Mead simplex: ``start`` and steps of 20 % (at least 0.5) per gain."""
    steps = np.maximum(0.2 * np.abs(start), 0.5)
    return np.vstack([start, start + np.diag(steps)])


@dataclass(frozen=True)
class SemiActiveGains:
    """Result of :func:`best_semi_active`.

    Attributes
    ----------
    law : SemiActiveDamping
        The tuned law (stiffness, low and high damping).
    cost : float
        Its mean cost over the training scenarios.
    evaluations : int
        Closed-loop runs of the training scenarios.
    """

    law: SemiActiveDamping
    cost: float
    evaluations: int


@reports_progress
def best_semi_active(config: FlexTeleopConfig | None = None, scenarios: int = 16,
                     seed: int = BASELINE_SEED, start: np.ndarray | None = None,
                     max_evaluations: int = 80, progress: bool | None = None
                     ) -> SemiActiveGains:
    """The hand-written semi-active damping law with its three numbers tuned for the paper's cost.

    Nelder–Mead over ``(K_r, B_low, B_high)`` of
    :class:`~teleopkit.rl.controllers.SemiActiveDamping`, each candidate run in closed loop
    through the certificate's safety layer on the training scenarios (every applied gain
    certified): a fair comparator for a tuner, with no learning.

    Parameters
    ----------
    config : FlexTeleopConfig, optional
        Environment settings and certificate (a class that covers changing damping, for example
        ``scheduled:0`` or ``tank``, for the law to be covered).
    scenarios : int
        Training scenarios, drawn from the setup of ``config`` with ``seed``.
    seed : int
        Their seed.
    start : ndarray, shape (2 n,), optional
        Constant gains to start from (for example the class's best static gains): the
        stiffness of joint 1 and its damping as both levels; default the centre of the set.
    max_evaluations : int
        Budget of closed-loop runs.
    progress : bool, optional
        Show the search on standard error: by default on a terminal only; ``False`` never,
        ``True`` always (:mod:`teleopkit.progress`).

    Returns
    -------
    SemiActiveGains
        The law, its cost and the number of runs.
    """
    from scipy.optimize import minimize  # deferred: a 0.7 s import

    from teleopkit.rl.evaluation import rollout

    config = config if config is not None else FlexTeleopConfig()
    certificate = config.safety_certificate()
    box = certificate.box
    n = box.n_joints
    if start is None:
        start = layer_for(certificate, config.control_period).fallback_action
    lower = np.array([box.lower[:n].max(), box.lower[n:].min(), box.lower[n:].min()])
    upper = np.array([box.upper[:n].min(), box.upper[n:].max(), box.upper[n:].max()])

    allowed = certificate.scheduled_set

    def law(x: np.ndarray) -> SemiActiveDamping:
        k, a, b = np.clip(x, lower, upper)
        if allowed is not None:  # the low level on the cone at least: the stiffness stays
            shape, cone, offset, _, _ = allowed.arrays()
            a, b = max(a, float(np.max(cone * shape * k / shape[0] + offset))), max(b, a)
        return SemiActiveDamping(float(k), float(min(a, b)), float(max(a, b)))

    @counting(_log, "semi-active law", max_evaluations)
    def objective(x: np.ndarray) -> float:
        run = rollout(law(x), scenarios, seed, config)
        return float(-run.reward.sum(axis=0).mean())

    x0 = np.array([start[0], start[n], 2.0 * start[n]])
    result = minimize(objective, x0, method="Nelder-Mead",
                      options={"maxfev": max_evaluations, "xatol": 1e-2, "fatol": 1e-2,
                               "initial_simplex": _simplex(x0)})
    return SemiActiveGains(law(result.x), float(result.fun), int(result.nfev))
