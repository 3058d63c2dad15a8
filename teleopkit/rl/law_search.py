"""Gain laws searched on the simulator: measured levels to gains, by CMA-ES.

A *gain law* maps what the remote side measures to remote gains through one linear layer::

    gains = low + span * softplus(W x + b),

with ``x`` the standardised *levels* of the adaptive observation
(:class:`~teleopkit.rl.features.AdaptiveObservation`: ``log10`` of moving averages of the squared
received operator rate and of both squared errors, per joint), the measured forward delay and
the safety layer's run-time state (the tank or budget level, when the class keeps one). Levels,
not signed signals: the physics is symmetric, so a gain that depends on the sign of an error
is noise. At ``W = 0, b = 0`` the law gives its *start*, the best constant gains of the class
for the setup: the search begins where the strongest constant comparator stands, and every
law it finds is a :class:`~teleopkit.rl.policy.GainPolicy` (one layer) that evaluation,
comparators and campaigns run as any tuner, its every gain projected by the safety layer.

The search is CMA-ES (Hansen, *The CMA evolution strategy: a tutorial*, 2016; the ``cma``
package) over ``(W, b)``. Each generation runs the population and the start gains on the same
fresh scenarios drawn from the setup (common random numbers), all in one batch of the simulator,
and scores each law by its cost relative to the start gains on each scenario, averaged: a
scenario that costs little weighs as much as one that costs much, so a law that helps the
cheap conditions cannot hide harm on them behind a costly one, and the other way round. A
``harm`` weight adds the mean excess over the start gains (``max(0, relative - 1)``, 1 by
default): the search then pays for every scenario a law makes worse. With ``references``
(constant gains spread over the box, run on the same scenarios) the reference of each scenario
is the cheapest of them and of the start: the objective is then the law's excess over the best
constant gains for that scenario, chosen with hindsight, which no family's own best constant
gains can beat on average. After every ``validate_every``
generations the distribution's mean is run on fixed validation scenarios, next to the start
gains; the best by the same objective there is kept, as the TD3 trainer keeps its best actor.
The start itself (the law at ``W = 0, b = 0``, objective 1 against itself) is the first
candidate, validated before the search: a search that finds no law better on the validation
scenarios keeps its start, never a law that does worse there than the start gains.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.files import atomic_write
from teleopkit.progress import reports_progress
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import closed_loop, episode_costs
from teleopkit.rl.policy import GainPolicy
from teleopkit.sim.scenarios import Scenario

__all__ = ["DECISION_SEED", "LawSearchConfig", "LawSearchResult", "law_features", "law_or_static",
           "law_start", "law_under", "search_gain_law", "stepped_aside"]

DECISION_SEED = 5_151
"""Seed of the scenarios on which a gain law's fall-back is decided (:func:`law_or_static`):
draws of the setup that neither the comparators' search (seed
:data:`~teleopkit.rl.baselines.BASELINE_SEED`) nor an evaluation (seed
:data:`~teleopkit.rl.evaluation.EVAL_SEED`) uses."""

_LN2 = math.log(2.0)

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LawSearchConfig:
    """Settings of :func:`search_gain_law`.

    Parameters
    ----------
    generations : int
        CMA-ES generations.
    population : int
        Laws per generation.
    scenarios : int
        Fresh scenarios per generation, shared by the population and the start gains (the batch
        simulated is ``(population + 1) * scenarios``).
    sigma : float
        Initial step size of CMA-ES in the weights' units (standardised levels).
    harm : float
        Weight of the mean excess cost over the start gains in the objective (0: the mean
        relative cost alone; 1, the shipped law's recipe, by default).
    seed : int
        Seed of the scenarios, the standardisation and CMA-ES.
    validate_every : int
        Generations between validations of the distribution's mean.
    validation_scenarios : int
        Fixed validation scenarios (seed ``validation_seed``, as the TD3 trainer's).
    validation_seed : int
        Their seed.
    references : tuple of tuple of float
        Constant gains (``2 n`` values each) run beside the laws on every generation's
        scenarios: each scenario's cheapest of them and of the start gains is the reference the
        objective measures the laws against (empty, the shipped law's recipe: the start gains
        alone). Spread over the box, they make the objective a law's excess over what the best
        constant gains for each scenario would have cost, so that scenarios whose best gains lie
        far from the start (a small operator from rest: near the softest corner) count as much
        as the others. Validation still compares with the start gains.
    """

    generations: int = 40
    population: int = 15
    scenarios: int = 64
    sigma: float = 0.15
    harm: float = 1.0
    seed: int = 0
    validate_every: int = 5
    validation_scenarios: int = 16
    validation_seed: int = 4_242
    references: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        for name in ("generations", "scenarios", "validate_every", "validation_scenarios"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.population < 2:
            raise ValueError(f"population must be at least 2, got {self.population}")
        if not self.sigma > 0 or not math.isfinite(self.sigma):
            raise ValueError(f"sigma must be positive, got {self.sigma}")
        if not (math.isfinite(self.harm) and self.harm >= 0):
            raise ValueError(f"harm must be finite and non-negative, got {self.harm}")
        references = tuple(tuple(float(g) for g in gains) for gains in self.references)
        if any(not (math.isfinite(g) and g > 0) for gains in references for g in gains):
            raise ValueError(f"references must be positive finite gains, got {references}")
        object.__setattr__(self, "references", references)


@dataclass(frozen=True)
class LawSearchResult:
    """What :func:`search_gain_law` returns.

    Attributes
    ----------
    policy : GainPolicy
        The best law by validation cost.
    log : pandas.DataFrame
        One row per validation: ``generation``, ``objective`` (the generation's best),
        ``validation_objective`` (the mean law's on the validation scenarios), its
        ``validation_cost`` and the start gains' ``start_cost`` there (means over the
        scenarios), ``wall_time`` and ``unsafe_actions`` (cumulative; must stay 0). The first
        row, generation 0, is the start's own (objectives 1).
    start : ndarray
        The start gains (``W = 0``); ``policy`` is the law that plays them (generation 0) when
        no law beat them on the validation scenarios.
    """

    policy: GainPolicy
    log: pd.DataFrame
    start: np.ndarray


def law_features(config: FlexTeleopConfig) -> np.ndarray:
    """Columns of the environment's observation a gain law reads.

    Parameters
    ----------
    config : FlexTeleopConfig
        Environment settings with ``observation="adaptive"``.

    Returns
    -------
    ndarray of int
        The levels (``3 n`` columns), the measured delay and the safety layer's run-time state.

    Raises
    ------
    ValueError
        If the observation is not the adaptive one (the paper's has no levels).
    """
    if config.observation != "adaptive":
        raise ValueError("a gain law reads the adaptive observation's levels; the environment "
                         f"observes {config.observation!r} (use observation='adaptive')")
    from teleopkit.safety.factory import layer_for

    n = config.params.n_joints
    layer = layer_for(config.safety_certificate(), config.control_period)
    return np.arange(8 * n, 11 * n + 1 + layer.run_time_state(1).shape[1])


def law_start(config: FlexTeleopConfig, progress: bool | None = None) -> np.ndarray:
    """Where a law starts: the best constant gains of the environment's class for its setup.

    Searched by :func:`~teleopkit.rl.baselines.best_static_gains` on the set of the
    environment's certificate, on scenarios of its setup. A gain on the box's lower edge is
    lifted by 1 % of its range: the law's map needs room below its start (what the law asks
    for is projected onto the certified set anyway).

    Parameters
    ----------
    config : FlexTeleopConfig
        Environment (setup and certificate).
    progress : bool, optional
        Show the search on standard error (default: on a terminal only).

    Returns
    -------
    ndarray, shape (2 n,)
        The start gains.
    """
    from teleopkit.rl.baselines import best_static_gains
    from teleopkit.safety.factory import layer_for

    certificate = config.safety_certificate()
    layer = layer_for(certificate, config.control_period)
    found = best_static_gains(layer, config=config, progress=progress).gains
    return np.asarray(certificate.box.lower, dtype=float) + _above(found, certificate)


def law_under(policy: GainPolicy, config: FlexTeleopConfig,
              progress: bool | None = None) -> GainPolicy:
    """A gain law moved onto the certificate it is to run under.

    A law is searched under one certificate, around its start: the best constant gains of
    that certificate's set. Under a certificate with another set (a shorter delay bound lets
    stiffer gains through, for example), the best constant gains move, and a law left around
    its old start would not use the room the new set gives (or would lean on the room it
    lost). The law's start moves by as much, per gain, measured on the setup of ``config``:
    ``start' - low' = (start - low) (best' - low') / (best - low)``, with ``best`` its best
    constant gains in the set the law was searched under and ``best'`` in the new set (the
    first a search in a set only: the simulated runs need not be certified by the old
    certificate, and no gain of them reaches a plant). A law whose start is the best constant
    gains of this setup in its old set thus starts at the best constant gains of the new set.
    Its weights are kept. Every gain the moved law asks for is projected by the safety layer
    of the new certificate, as any tuner's.

    Parameters
    ----------
    policy : GainPolicy
        A policy; one not searched by :func:`search_gain_law` is returned as it is.
    config : FlexTeleopConfig
        The setup and the certificate (``config.certificate``) it is to run under.
    progress : bool, optional
        Show the two searches on standard error (default: on a terminal only).

    Returns
    -------
    GainPolicy
        ``policy`` itself when the certificate's set is the one it was searched under (no
        search), else the moved law, whose metadata records the new certificate and start and
        the gains the move was measured with (``moved``).
    """
    from teleopkit.rl.baselines import best_static_gains
    from teleopkit.rl.comparison import policy_certificate  # it imports this module
    from teleopkit.safety.factory import layer_for

    if "law_search" not in policy.metadata:
        return policy
    searched = policy_certificate(policy)
    target = config.safety_certificate()
    if _set_of(searched) == _set_of(target):
        return policy
    _log.info("moving the gain law onto the %s certificate for delays up to %s s",
              target.gain_variation, list(target.delay_bounds))
    before = best_static_gains(layer_for(searched, config.control_period), config=config,
                               progress=progress).gains
    after = best_static_gains(config=config, progress=progress).gains
    low_after = np.asarray(target.box.lower, dtype=float)
    start = policy.low + policy.span * _LN2
    moved = low_after + policy.span * _LN2 * _above(after, target) / _above(before, searched)
    metadata = {**policy.metadata, "certificate": target.to_dict(), "start": moved.tolist(),
                "moved": {"start": start.tolist(), "certificate": searched.to_dict(),
                          "setup": config.setup.fingerprint, "best_static": before.tolist(),
                          "best_static_after": after.tolist()}}
    return GainPolicy(policy.weights, policy.obs_mean, policy.obs_std, low_after,
                      (moved - low_after) / _LN2, metadata, policy.obs_range)


def law_or_static(policy: GainPolicy, config: FlexTeleopConfig, static: np.ndarray,
                  scenarios: int = 32, seed: int = DECISION_SEED) -> GainPolicy:
    """A gain law, or the constant gains it steps aside for on the setup it runs on.

    The law and ``static``, the best constant gains of its class for the setup of ``config``
    (searched on the setup's training scenarios, as the comparators are), run on fresh
    scenarios of the setup: neither those the constant gains were fitted to, which favour them
    (on a varied setup enough to set aside a law that pays), nor the held-out ones of an
    evaluation. Where the law costs more there on average, it steps aside: the law returned
    plays ``static`` and nothing else (its output map's span is zero; its weights are kept, to
    say which law stepped aside), and its metadata records both costs (``stepped_aside``).
    A law that adapts across conditions can still lose to the constant gains of one
    condition (a small operator from rest, for example: their best lie near the box's soft
    corner); this is its fall-back, decided per setup, before any run.

    Parameters
    ----------
    policy : GainPolicy
        A policy; one not searched by :func:`search_gain_law`, or one that already stepped
        aside, is returned as it is.
    config : FlexTeleopConfig
        The setup and certificate it runs under (moved onto it first: :func:`law_under`).
    static : ndarray, shape (2 n,)
        The best constant gains of the certificate's set for the setup
        (``class_static`` of :class:`~teleopkit.rl.comparators.Comparators`).
    scenarios : int
        Scenarios the decision is made on.
    seed : int
        Their seed (by default :data:`DECISION_SEED`).

    Returns
    -------
    GainPolicy
        ``policy`` itself when it is no dearer than ``static`` on those scenarios (to
        rounding), else the law that plays ``static``.
    """
    from teleopkit.rl.comparators import policy_observation, tuner_controller
    from teleopkit.rl.controllers import ConstantGains

    if "law_search" not in policy.metadata or "stepped_aside" in policy.metadata:
        return policy
    static = np.asarray(static, dtype=float)
    drawn = config.setup.scenarios(seed, scenarios)
    observed = replace(config, observation=policy_observation(policy))
    law_cost = float(episode_costs(tuner_controller(policy), drawn, observed)[0].mean())
    static_cost = float(episode_costs(ConstantGains(static), drawn, config)[0].mean())
    if law_cost <= static_cost * (1.0 + 1e-9):  # a tie to rounding keeps the law
        return policy
    _log.info("the gain law steps aside for the constant gains %s on setup %s (%d fresh "
              "scenarios: %.5g against %.5g)", static.round(4).tolist(),
              config.setup.fingerprint, scenarios, law_cost, static_cost)
    aside = {"law_cost": law_cost, "static_cost": static_cost, "static": static.tolist(),
             "scenarios": scenarios, "seed": seed, "setup": config.setup.fingerprint}
    return GainPolicy(policy.weights, policy.obs_mean, policy.obs_std, static,
                      np.zeros_like(static), {**policy.metadata, "stepped_aside": aside},
                      policy.obs_range)


def stepped_aside(policy: GainPolicy) -> str | None:
    """Why a law plays constant gains on its setup, in words (None if it runs as searched).

    Parameters
    ----------
    policy : GainPolicy
        A policy, for example returned by :func:`law_or_static`.

    Returns
    -------
    str or None
        ``"steps aside on this setup: ..."``, with both costs and the gains it plays.
    """
    aside = policy.metadata.get("stepped_aside")
    if aside is None:
        return None
    gains = ", ".join(f"{g:.3g}" for g in aside["static"])
    return (f"steps aside on this setup: on {aside['scenarios']} fresh scenarios of it, it cost "
            f"{aside['law_cost']:.5g} against {aside['static_cost']:.5g} for the best constant "
            f"gains of its class ({gains}), which its row plays")


def _set_of(certificate: GainCertificate) -> str:
    """What a certificate's safety layer enforces: its class, polytope and scheduled set."""
    data = certificate.to_dict()
    return json.dumps([data["gain_variation"], data["polytope"],
                       (data.get("details") or {}).get("set")], sort_keys=True)


def _above(gains: np.ndarray, certificate: GainCertificate) -> np.ndarray:
    """How far gains lie above the box's lower corner, at least 1 % of its range."""
    low, high = (np.asarray(c, dtype=float) for c in (certificate.box.lower,
                                                       certificate.box.upper))
    return np.maximum(gains - low, 0.01 * (high - low))


class _Laws:
    """Several gain laws side by side: law ``p`` drives lanes ``p S .. (p + 1) S - 1``.

    Weights are rounded to single precision, as a policy file stores them: the law run here is
    the law saved.
    """

    def __init__(self, thetas: np.ndarray, columns: np.ndarray, low: np.ndarray,
                 span: np.ndarray, seen: _Seen) -> None:
        thetas = np.asarray(thetas, dtype=np.float32).astype(np.float64)
        width = seen.mean.size
        count, actions = len(thetas), len(low)
        self.weights = np.zeros((count, actions, width))
        self.weights[:, :, columns] = thetas[:, :actions * columns.size].reshape(
            count, actions, columns.size)
        self.bias = thetas[:, actions * columns.size:]
        self.low, self.span, self.seen = low, span, seen

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        seen = self.seen
        x = (np.clip(obs, seen.lowest, seen.highest) - seen.mean) / seen.std
        x = x.reshape(len(self.weights), -1, obs.shape[1])
        z = np.einsum("psd,pad->psa", x, self.weights) + self.bias[:, None, :]
        return (self.low + self.span * np.logaddexp(0.0, z)).reshape(-1, len(self.low))

    def policy(self, metadata: dict[str, Any]) -> GainPolicy:
        """The first law as a one-layer :class:`GainPolicy`."""
        seen = self.seen
        return GainPolicy([(self.weights[0], self.bias[0])], seen.mean, seen.std, self.low,
                          self.span, metadata, (seen.lowest, seen.highest))


def _costs(controller: Any, scenario: Scenario, config: FlexTeleopConfig,
           count: int) -> tuple[np.ndarray, int]:
    """Episode costs ``(count, S)`` of ``count`` laws on ``scenario`` repeated, unsafe actions."""
    costs, unsafe = episode_costs(controller, scenario.repeat(count), config)
    return costs.reshape(count, scenario.batch), unsafe


def _reference(start: np.ndarray, references: np.ndarray, scenario: Scenario,
               config: FlexTeleopConfig) -> tuple[np.ndarray, int]:
    """Per scenario, the cheapest of the start gains' ``start`` costs and the references'."""
    if not len(references):
        return start, 0
    lanes = np.repeat(references, scenario.batch, axis=0)  # as Scenario.repeat lays them out
    costs, unsafe = episode_costs(lambda obs: lanes, scenario.repeat(len(references)), config)
    return np.minimum(start, costs.reshape(len(references), -1).min(axis=0)), unsafe


def _objective(costs: np.ndarray, start: np.ndarray, harm: float) -> np.ndarray:
    """Per law: mean cost relative to the start gains', plus ``harm`` times the mean excess."""
    relative = costs / start
    return relative.mean(axis=1) + harm * np.maximum(relative - 1.0, 0.0).mean(axis=1)


class _Seen(NamedTuple):
    """Observations seen before the search: their mean, spread and range."""

    mean: np.ndarray
    std: np.ndarray
    lowest: np.ndarray
    highest: np.ndarray


def _observed(config: FlexTeleopConfig, start: np.ndarray, low: np.ndarray,
              settings: LawSearchConfig) -> _Seen:
    """The observation under constant gains spread around the start.

    Uniform in ``[low, 2 start - low]`` per scenario: the levels and the safety layer's state
    vary as they will under the laws (under the start alone the tank never moves). A law reads
    its inputs clipped into the range seen here: it never extrapolates beyond the setup it was
    searched for (a delay shorter than any the setup draws reads as the shortest one).
    """
    rng = np.random.default_rng(settings.seed)
    scenario = config.setup.scenarios(rng, settings.scenarios)
    gains = low + rng.uniform(size=(settings.scenarios, len(start))) * 2 * (start - low)
    run = closed_loop(lambda obs: gains, scenario, config)
    obs = run.obs.reshape(-1, run.obs.shape[-1])
    return _Seen(obs.mean(axis=0), np.maximum(obs.std(axis=0), 1e-3), obs.min(axis=0),
                 obs.max(axis=0))


@reports_progress
def search_gain_law(start: np.ndarray, settings: LawSearchConfig | None = None,
                    config: FlexTeleopConfig | None = None, out_dir: str | Path | None = None,
                    progress: bool | None = None) -> LawSearchResult:
    """Search a gain law for the environment's setup by CMA-ES (see the module notes).

    Parameters
    ----------
    start : ndarray, shape (2 n,)
        The law at ``W = 0``: constant gains inside the certified set, strictly above the
        box's lower corner (the best constant gains of the class, typically
        :func:`~teleopkit.rl.baselines.best_static_gains`).
    settings : LawSearchConfig, optional
        Search settings (defaults if omitted).
    config : FlexTeleopConfig, optional
        Environment (setup, certificate, reward) with ``observation="adaptive"``; by default
        the paper's setup under its default certificate.
    out_dir : str or Path, optional
        Where to write ``best_policy.npz``, ``search_log.csv`` and ``config.json`` (nothing
        written if omitted).
    progress : bool, optional
        Show the generations on standard error (default: on a terminal only).

    Returns
    -------
    LawSearchResult
        The best law by validation, the log and the start gains.

    Raises
    ------
    ValueError
        If the observation is not the adaptive one or ``start`` is not above the box's lower
        corner.
    RuntimeError
        If an applied gain left the certified set (never expected).
    """
    import cma  # deferred: only the search needs it

    settings = settings if settings is not None else LawSearchConfig()
    config = config if config is not None else FlexTeleopConfig(observation="adaptive")
    columns = law_features(config)
    certificate = config.safety_certificate()
    low = np.asarray(certificate.box.lower, dtype=float)
    start = np.asarray(start, dtype=float)
    if start.shape != low.shape or not np.all(start > low):
        raise ValueError(f"the law's start {start.tolist()} must lie above the box's lower "
                         f"corner {low.tolist()}")
    if any(len(gains) != low.size for gains in settings.references):
        raise ValueError(f"references need {low.size} gains each, got {settings.references}")
    references = np.array(settings.references, dtype=float).reshape(-1, low.size)
    span = (start - low) / _LN2
    seen = _observed(config, start, low, settings)
    size = low.size * columns.size + low.size  # W on the law's columns, then b
    search = cma.CMAEvolutionStrategy(np.zeros(size), settings.sigma,
                                      {"popsize": settings.population, "seed": settings.seed + 1,
                                       "verbose": -9})
    validation = config.setup.scenarios(np.random.default_rng(settings.validation_seed),
                                        settings.validation_scenarios)

    def laws(thetas: np.ndarray) -> _Laws:
        return _Laws(thetas, columns, low, span, seen)

    metadata = {"recipe": "gain law (CMA-ES)", "law_search": asdict(settings),
                "start": start.tolist(), "gain_variation": certificate.gain_variation,
                "certificate": certificate.to_dict(), "setup": config.setup.record,
                "observation": config.observation,
                "decision_period": config.decision_period}
    began = time.perf_counter()
    still = laws(np.zeros((1, size)))
    checked, unsafe = _costs(still, validation, config, 1)
    rows = [_validated(0, 1.0, 1.0, checked[0], checked[0], began, unsafe)]
    best = (1.0, still.policy({**metadata, "generation": 0, "validation_objective": 1.0,
                               "validation_cost": rows[0]["validation_cost"]}))
    for generation in range(1, settings.generations + 1):
        thetas = np.asarray(search.ask())
        rng = np.random.default_rng([settings.seed, generation])
        scenario = config.setup.scenarios(rng, settings.scenarios)
        costs, count = _costs(laws(np.vstack([np.zeros(size), thetas])), scenario, config,
                              len(thetas) + 1)
        unsafe += count
        reference, count = _reference(costs[0], references, scenario, config)
        unsafe += count
        objective = _objective(costs[1:], reference, settings.harm)
        search.tell(list(thetas), objective.tolist())
        _log.info("gain law search: generation %d of %d, best objective %.4f", generation,
                  settings.generations, float(objective.min()))
        if generation % settings.validate_every and generation != settings.generations:
            continue
        current = laws(np.vstack([search.mean, np.zeros(size)]))
        checked, count = _costs(current, validation, config, 2)
        unsafe += count
        score = float(_objective(checked[:1], checked[1], settings.harm)[0])
        rows.append(_validated(generation, float(objective.min()), score, checked[0],
                               checked[1], began, unsafe))
        if score < best[0]:
            best = (score, current.policy({**metadata, "generation": generation,
                                           "validation_objective": score,
                                           "validation_cost": rows[-1]["validation_cost"]}))
        if out_dir is not None:
            _save(Path(out_dir), best[1], pd.DataFrame(rows), settings)
    if unsafe:
        raise RuntimeError(f"{unsafe} applied gains left the certified set")
    return LawSearchResult(best[1], pd.DataFrame(rows), start)


def _validated(generation: int, objective: float, score: float, costs: np.ndarray,
               start_costs: np.ndarray, began: float, unsafe: int) -> dict[str, float]:
    """A row of the search's log: a law's validation beside the start gains'."""
    return {"generation": generation, "objective": objective, "validation_objective": score,
            "validation_cost": float(costs.mean()), "start_cost": float(start_costs.mean()),
            "wall_time": time.perf_counter() - began, "unsafe_actions": unsafe}


def _save(out_dir: Path, policy: GainPolicy, log: pd.DataFrame,
          settings: LawSearchConfig) -> None:
    """The best law, the log and the settings, each written atomically."""
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write(out_dir / "best_policy.npz", policy.save)
    atomic_write(out_dir / "search_log.csv", lambda path: log.to_csv(path, index=False))
    atomic_write(out_dir / "config.json",
                 lambda path: path.write_text(json.dumps(asdict(settings), indent=2)))
