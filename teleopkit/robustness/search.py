"""Falsification search: the worst delays and gains an adversary can pick inside a certified set.

:mod:`teleopkit.robustness.falsification` samples adversarial scenarios at random; this module
*optimises* them.
The adversary picks

* the delays, anywhere in ``[0, T_l*]`` and ``[0, T_r*]``: either a square wave per channel
  (``delays="square"``: two levels, a half period from one control period to 2 s and a phase;
  the fast bang-bang switching of adversarial tests), or ``segments`` piecewise-constant values at
  switching times it chooses (``delays="segments"``);
* the remote gains, anywhere in the certificate's polytope (a point of the polytope's bounding box
  projected exactly onto the polytope by the :class:`~teleopkit.safety.SafetyLayer`): one frozen
  point per run when the certificate covers frozen gains only; one point per segment, switching at
  the chosen times, for ``switching`` certificates; for ``rate:R`` certificates, the gains move
  towards each segment's point at the certified rate;
* the operator's reference gains in ``[-1, 1]``.

Inside a scheduled class (``scheduled:L``, ``tank``) the gains pass, period by period, through
the class's safety layer (:class:`~teleopkit.safety.schedule.ScheduleLayer`, which spends the
budget or the tank), and the plant runs as the proof assumes it: no torque saturation and the
operator holding the origin (a passive operator; a moving reference would inject energy). The
storage of the class is then measured along every run (``storage_ratio``: the largest ``V(t) /
V(0)``, or ``(V + tank) / (V(0) + T0)`` with a tank), against its proven bound
(``storage_bound``: ``exp(L)``, or 1).

The objective, maximised by CMA-ES (package ``cma``) or random search, population by population,
each population simulated as one batch of the :class:`~teleopkit.sim.simulator.Simulator`, is one of

* ``"energy_growth"``: log of the peak mechanical energy (both arms, rotors, joint springs) over
  the last quarter of the run over that of the second quarter;
* ``"error_growth"``: the same ratio for ``||e_track|| + ||e_damp||``;
* ``"energy"``: log of the peak mechanical energy over the second half of the run;
* ``"storage"`` (scheduled classes): log of ``storage_ratio``.

A positive growth means the motion grows in spite of the decaying operator reference. The worst
case found comes back as a :class:`SearchResult` with its decision, its metrics and its replayed
trajectory. A run is ``diverged`` by the criterion of :mod:`teleopkit.sim.divergence`.

This is evidence, never proof: finding nothing proves nothing, and a divergence found inside a
certified set (``covered=True``, :attr:`SearchResult.finding`) contradicts the certificate (or
its assumptions: the linearisation of an LMI certificate, the torque saturation of the
simulator) and must be reported. With ``covered=False`` the adversary used a gain class the
certificate does not cover (for example switching gains inside the closed form's frozen-gain set,
which the paper claims is safe): a divergence there refutes that claim, not the certificate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import closed_loop
from teleopkit.robustness.adversary import Decision, SearchSpace, decode, gain_schedule
from teleopkit.safety.layer import SafetyLayer
from teleopkit.safety.loop import CertifiedLoop
from teleopkit.setup import Setup
from teleopkit.sim.divergence import Divergence, position_magnitude
from teleopkit.sim.energy import mechanical_energy
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.trajectory import Trajectory

__all__ = ["OBJECTIVES", "SearchResult", "search"]

OBJECTIVES = ("energy_growth", "error_growth", "energy", "storage")
"""Objectives the adversary maximises (see the module docstring)."""

Objective = Literal["energy_growth", "error_growth", "energy", "storage"]
Method = Literal["cma", "random"]

_PENALTY = 1e6
"""Objective handed to the optimiser for a non-finite run (the report keeps ``inf``)."""


def _simulate(space: SearchSpace, decision: Decision) -> tuple[Trajectory, np.ndarray]:
    """Run a batch of adversarial scenarios: the trajectory and the budget or tank levels."""
    scenario = Scenario(space.params, decision.forward, decision.backward,
                        decision.reference_gains)
    if space.controller is not None:
        config = FlexTeleopConfig(Setup.from_params(space.params), space.certificate,
                                  episode_length=space.duration, dt=space.dt,
                                  control_period=space.control_period)
        run = closed_loop(space.controller, scenario, config)
        return run.trajectory, run.levels
    sim = Simulator(scenario, space.dt, space.control_period)
    if space.variation.scheduled:
        return CertifiedLoop(space.layer()).run(sim, gain_schedule(space, decision))
    trajectory = sim.run(space.duration, gain_schedule(space, decision))
    return trajectory, np.full((*trajectory.t.shape, scenario.batch), np.nan)


def _growth(signal: np.ndarray) -> np.ndarray:
    """Log of the last-quarter peak over the second-quarter peak, per run."""
    quarter = max(1, signal.shape[0] // 4)
    with np.errstate(all="ignore"):
        late = np.log(signal[-quarter:].max(axis=0))
        return late - np.log(signal[quarter:2 * quarter].max(axis=0))


def _storage_ratio(space: SearchSpace, trajectory: Trajectory,
                   levels: np.ndarray) -> np.ndarray:
    """Largest ``(V + tank) / (V(0) + T0)`` of each run (NaN outside the scheduled classes)."""
    if not space.variation.scheduled:
        return np.full(trajectory.state.shape[1], np.nan)
    storage = space.certificate.storage
    assert storage is not None
    with np.errstate(all="ignore"):
        total = storage.value(space.params, trajectory) + np.nan_to_num(levels)
        return np.nan_to_num(total / total[0], nan=np.inf).max(axis=0)


def _score(space: SearchSpace, run: tuple[Trajectory, np.ndarray],
           objective: str) -> pd.DataFrame:
    """Objective, growth ratios, storage ratio and divergence of every run of a batch."""
    trajectory, levels = run
    state = trajectory.state
    finite = np.all(np.isfinite(state), axis=(0, 2))
    magnitude = position_magnitude(state[1:])
    with np.errstate(all="ignore"):
        energy = mechanical_energy(space.params, trajectory.state)
    error = (np.linalg.norm(trajectory.e_track, axis=-1)
             + np.linalg.norm(trajectory.e_damp, axis=-1))
    half = energy.shape[0] // 2
    ratio = _storage_ratio(space, trajectory, levels)
    with np.errstate(all="ignore"):
        values = {"energy_growth": _growth(energy), "error_growth": _growth(error),
                  "energy": np.log(energy[half:].max(axis=0)), "storage": np.log(ratio)}
    verdict = Divergence(space.divergence_radius).assess(magnitude, finite, space.duration)
    table = pd.DataFrame({"objective": values[objective], "energy_growth": values["energy_growth"],
                          "error_growth": values["error_growth"], "growth": verdict["growth"],
                          "max_position": verdict["max_position"], "storage_ratio": ratio})
    table.loc[~finite, ["objective", "energy_growth", "error_growth"]] = np.inf
    table["diverged"] = verdict["diverged"]
    return table


@dataclass(frozen=True)
class SearchResult:
    """The worst case a falsification search found.

    Parameters
    ----------
    method : str
        Certification method of the certificate searched.
    gain_variation : str
        Gain class of the certificate.
    switching : bool
        Whether the adversary switched gains.
    delays : str
        Delay pattern (``"square"`` or ``"segments"``).
    covered : bool
        Whether the adversary stayed within what the certificate covers.
    objective : str
        Objective maximised.
    value : float
        Worst (largest) objective found.
    diverged : bool
        Whether the worst run diverged.
    energy_growth, error_growth : float
        Log growth ratios of the worst run (see the module docstring).
    growth : float
        Last-quarter over second-quarter peak position of the worst run (not logarithmic).
    max_position : float
        Peak position magnitude of the worst run (rad).
    storage_ratio : float
        Largest storage ratio of the worst run (scheduled classes; NaN otherwise).
    storage_bound : float
        Its proven bound (``exp(L)``, 1 with a tank; NaN otherwise).
    evaluations : int
        Runs simulated.
    decision : Decision
        The worst run's choices (a batch of one).
    trajectory : pandas.DataFrame
        The worst run replayed (:meth:`~teleopkit.sim.simulator.Trajectory.to_frame` columns).
    history : pandas.DataFrame
        Every evaluation: ``generation``, ``objective``, ``diverged``.
    search : str
        ``"cma"`` or ``"random"``.
    """

    method: str
    gain_variation: str
    switching: bool
    delays: str
    covered: bool
    objective: str
    value: float
    diverged: bool
    energy_growth: float
    error_growth: float
    growth: float
    max_position: float
    storage_ratio: float
    storage_bound: float
    evaluations: int
    decision: Decision
    trajectory: pd.DataFrame
    history: pd.DataFrame = field(repr=False)
    search: str = "cma"

    @property
    def finding(self) -> bool:
        """A divergence, or a storage above its bound, inside what the certificate covers.

        Either contradicts the certificate (or one of its assumptions).
        """
        above = self.storage_ratio > self.storage_bound * (1.0 + 1e-6)
        return bool(self.covered and (self.diverged or above))

    def summary(self) -> str:
        """One line: what was searched and what the worst case did."""
        scope = "inside the certified class" if self.covered else "OUTSIDE the certified class"
        verdict = "DIVERGED" if self.diverged else "bounded"
        return (f"{self.method} ({self.gain_variation}), gains "
                f"{'switching' if self.switching else 'frozen'}, {self.delays} delays, {scope}: "
                f"worst {self.objective} "
                f"{self.value:.4g} after {self.evaluations} runs ({self.search}), {verdict}, "
                f"peak position {self.max_position:.3g} rad"
                + (f", storage ratio {self.storage_ratio:.4g} (bound {self.storage_bound:.4g})"
                   if math.isfinite(self.storage_bound) else ""))

    def to_row(self) -> dict[str, Any]:
        """The scalar fields as one table row."""
        return {"method": self.method, "gain_variation": self.gain_variation,
                "switching": self.switching, "delays": self.delays, "covered": self.covered,
                "objective": self.objective, "value": self.value, "diverged": self.diverged,
                "energy_growth": self.energy_growth, "error_growth": self.error_growth,
                "growth": self.growth, "max_position": self.max_position,
                "storage_ratio": self.storage_ratio, "storage_bound": self.storage_bound,
                "evaluations": self.evaluations, "search": self.search, "finding": self.finding}


class _Optimiser:
    """Ask / tell over ``[0, 1]^d``: CMA-ES (package ``cma``) or uniform random search."""

    def __init__(self, method: str, dimension: int, population: int, budget: int,
                 seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.population = population
        self.es: Any = None
        if method == "cma":
            self.es = _cma_strategy(dimension, population, budget, self.rng)
        elif method != "random":
            raise ValueError(f"search method must be 'cma' or 'random', got {method!r}")
        self.dimension = dimension

    def ask(self) -> np.ndarray:
        if self.es is None:
            return self.rng.random((self.population, self.dimension))
        return np.array(self.es.ask())

    def tell(self, x: np.ndarray, values: np.ndarray) -> None:
        if self.es is not None:
            self.es.tell(list(x), list(-np.minimum(values, _PENALTY)))

    def stopped(self) -> bool:
        return bool(self.es is not None and self.es.stop())


def _cma_strategy(dimension: int, population: int, budget: int, rng: np.random.Generator) -> Any:
    try:
        import cma
    except ModuleNotFoundError:
        raise ModuleNotFoundError("CMA-ES search needs cma: pip install 'teleopkit[campaign]' "
                                  "(or use method='random')") from None
    options = {"bounds": [0.0, 1.0], "popsize": population, "maxfevals": budget,
               "verbose": -9, "seed": math.nan, "tolfun": 0.0, "tolflatfitness": budget,
               "randn": lambda lam, n: rng.standard_normal((lam, n))}
    return cma.CMAEvolutionStrategy(np.full(dimension, 0.5), 0.3, options)


def _check_search(space: SearchSpace, budget: int, population: int, objective: str) -> None:
    for name, value in (("budget", budget), ("population", population)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 2:
            raise ValueError(f"{name} must be an integer >= 2, got {value!r}")
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    if objective == "storage" and not space.variation.scheduled:
        raise ValueError(f"the storage objective needs a scheduled:L or tank certificate, not "
                         f"{space.variation}")


def search(space: SearchSpace, objective: Objective = "energy_growth", method: Method = "cma",
           budget: int = 256, population: int = 16, seed: int = 0) -> SearchResult:
    """Search for the adversarial delays and gains that maximise ``objective``.

    Parameters
    ----------
    space : SearchSpace
        Teleoperator, certificate and adversary's freedom.
    objective : {"energy_growth", "error_growth", "energy", "storage"}
        What the adversary maximises.
    method : {"cma", "random"}
        CMA-ES in ``[0, 1]^d`` (box-bounded) or uniform random search.
    budget : int
        Runs to simulate (rounded up to whole populations).
    population : int
        Runs per generation, simulated as one batch.
    seed : int
        Seed of the search.

    Returns
    -------
    SearchResult
        The worst run found, replayed, with the search history.
    """
    _check_search(space, budget, population, objective)
    layer = space.layer()
    optimiser = _Optimiser(method, space.dimension, population, budget, seed)
    best: tuple[float, np.ndarray] | None = None
    history = []
    generation = 0
    while generation * population < budget and not optimiser.stopped():
        x = np.clip(optimiser.ask(), 0.0, 1.0)
        scores = _score(space, _simulate(space, decode(space, x, layer)), objective)
        values = scores["objective"].to_numpy()
        optimiser.tell(x, values)
        history.append(scores.assign(generation=generation))
        top = int(np.argmax(np.nan_to_num(values, nan=-np.inf)))
        if best is None or values[top] > best[0]:
            best = (float(values[top]), x[top])
        generation += 1
    assert best is not None
    return _result(space, objective, method, best[1], pd.concat(history, ignore_index=True),
                   layer)


def _result(space: SearchSpace, objective: str, method: str, x: np.ndarray,
            history: pd.DataFrame, layer: SafetyLayer) -> SearchResult:
    """Replay the worst decision alone and package it."""
    decision = decode(space, x[None], layer)
    run = _simulate(space, decision)
    score = _score(space, run, objective).iloc[0]
    return SearchResult(
        space.certificate.method, space.certificate.gain_variation, bool(space.switching),
        space.delays, space.covered, objective, float(score["objective"]), bool(score["diverged"]),
        float(score["energy_growth"]), float(score["error_growth"]), float(score["growth"]),
        float(score["max_position"]), float(score["storage_ratio"]), space.storage_bound,
        len(history), decision, run[0].to_frame(0),
        history[["generation", "objective", "diverged"]], method)
