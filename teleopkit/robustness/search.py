"""Falsification search: the worst delays and gains an adversary can pick inside a certified set.

:mod:`teleopkit.robustness.sampling` samples adversarial scenarios at random; this module
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

The objective, maximised by CMA-ES (package ``cma``) or random search, population by population,
each population simulated as one batch of the :class:`~teleopkit.sim.simulator.Simulator`, is one of

* ``"energy_growth"``: log of the peak mechanical energy (both arms, rotors, joint springs) over
  the last quarter of the run over that of the second quarter;
* ``"error_growth"``: the same ratio for ``||e_track|| + ||e_damp||``;
* ``"energy"``: log of the peak mechanical energy over the second half of the run.

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

from teleopkit.certification.certificate import GainCertificate
from teleopkit.certification.classes import GainVariation, parse_gain_variation
from teleopkit.delays.adversarial import PiecewiseDelay, SquareWaveDelay
from teleopkit.model.dynamics import kinetic_energy, remote_energy
from teleopkit.model.params import TeleoperatorParams
from teleopkit.safety.layer import SafetyLayer
from teleopkit.sim.divergence import DIVERGENCE_RADIUS, Divergence, position_magnitude
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.state import StateLayout
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT
from teleopkit.sim.trajectory import Trajectory

__all__ = [
    "OBJECTIVES",
    "Decision",
    "SearchResult",
    "SearchSpace",
    "decode",
    "gain_schedule",
    "search",
]

OBJECTIVES = ("energy_growth", "error_growth", "energy")
"""Objectives the adversary maximises (see the module docstring)."""

Objective = Literal["energy_growth", "error_growth", "energy"]
Method = Literal["cma", "random"]

_PENALTY = 1e6
"""Objective handed to the optimiser for a non-finite run (the report keeps ``inf``)."""


@dataclass(frozen=True)
class SearchSpace:
    """What the adversary may choose, from a certificate.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    certificate : GainCertificate
        Its polytope bounds the gains, its ``delay_bounds`` the delays.
    switching : bool, optional
        Whether gains change between segments; by default as the certificate's gain class
        (frozen: one gain point per run). ``True`` on a frozen-gain certificate probes outside
        what it covers.
    delays : {"square", "segments"}
        Square-wave delays per channel, or piecewise-constant delays on the segments.
    segments : int
        Piecewise-constant intervals (of the gains when switching, of ``segments`` delays).
    duration : float
        Seconds per run.
    dt : float
        Integration step.
    control_period : float
        Gain hold period.
    divergence_radius : float
        Position magnitude (rad) that counts as divergence.
    """

    params: TeleoperatorParams
    certificate: GainCertificate
    switching: bool | None = None
    delays: str = "square"
    segments: int = 8
    duration: float = 20.0
    dt: float = DEFAULT_DT
    control_period: float = CONTROL_PERIOD
    divergence_radius: float = DIVERGENCE_RADIUS

    def __post_init__(self) -> None:
        if self.certificate.box.n_joints != self.params.n_joints:
            raise ValueError(f"certificate has {self.certificate.box.n_joints} joints, the "
                             f"teleoperator {self.params.n_joints}")
        if self.certificate.polytope.is_empty():
            raise ValueError("the certificate's gain polytope is empty: nothing to search")
        if isinstance(self.segments, bool) or not isinstance(self.segments, int) or \
                self.segments < 1:
            raise ValueError(f"segments must be an integer >= 1, got {self.segments!r}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be positive, got {self.duration}")
        if self.delays not in ("square", "segments"):
            raise ValueError(f"delays must be 'square' or 'segments', got {self.delays!r}")
        if self.switching is None:
            object.__setattr__(self, "switching", self.variation.kind != "frozen")

    @property
    def variation(self) -> GainVariation:
        """The certificate's :class:`~teleopkit.certification.GainVariation`."""
        return parse_gain_variation(self.certificate.gain_variation)

    @property
    def covered(self) -> bool:
        """Whether every run of the space lies within what the certificate covers."""
        frozen_only = self.variation.kind == "frozen"
        return bool(self.certificate.polytope_certified and not (self.switching and frozen_only))

    @property
    def rate(self) -> float:
        """Largest gain rate (per second) of a rate-bounded certificate, else ``inf``."""
        variation = self.variation
        return float(variation.rate) if variation.kind == "rate" else math.inf

    @property
    def gain_points(self) -> int:
        """Gain points per run: one per segment when switching, else one."""
        return self.segments if self.switching else 1

    @property
    def blocks(self) -> dict[str, int]:
        """Lengths of the parts of a decision vector, in order."""
        n, k = self.params.n_joints, self.segments
        uses_times = self.switching or self.delays == "segments"
        return {"times": k - 1 if uses_times else 0,
                "delays": 2 * k if self.delays == "segments" else 8,
                "gains": 2 * n * self.gain_points, "reference": n}

    @property
    def dimension(self) -> int:
        """Length of a decision vector in ``[0, 1]^d``."""
        return sum(self.blocks.values())


@dataclass(frozen=True)
class Decision:
    """Decoded adversarial choices of a batch of runs.

    Parameters
    ----------
    times : ndarray, shape (B, K)
        Segment start times (the first is 0).
    gains : ndarray, shape (B, K, 2 n)
        Target gains on each segment (inside the polytope).
    reference_gains : ndarray, shape (B, n)
        Operator reference gains.
    forward, backward : DelayProfile
        Delays ``T_l`` and ``T_r`` of the batch (:class:`~teleopkit.delays.SquareWaveDelay`
        or :class:`~teleopkit.delays.PiecewiseDelay`).
    """

    times: np.ndarray
    gains: np.ndarray
    reference_gains: np.ndarray
    forward: SquareWaveDelay | PiecewiseDelay
    backward: SquareWaveDelay | PiecewiseDelay

    def describe(self, b: int = 0) -> dict[str, Any]:
        """Plain data of one run: segment times, gains, reference gains, delay parameters.

        Parameters
        ----------
        b : int
            Index of the run in the batch.

        Returns
        -------
        dict
            JSON-ready description.
        """
        delays = {}
        for name, profile in (("forward", self.forward), ("backward", self.backward)):
            if isinstance(profile, SquareWaveDelay):
                delays[name] = {"low": float(profile.low[b]), "high": float(profile.high[b]),
                                "half_period": float(profile.half_period[b]),
                                "phase": float(profile.phase[b])}
            else:
                delays[name] = {"times": profile.times[b].tolist(),
                                "values": profile.values[b].tolist()}
        return {"times": self.times[b].tolist(), "gains": self.gains[b].tolist(),
                "reference_gains": self.reference_gains[b].tolist(), "delays": delays}


def _delay_profiles(space: SearchSpace, u: np.ndarray,
                    times: np.ndarray) -> tuple[SquareWaveDelay | PiecewiseDelay, ...]:
    """Forward and backward delays from their block of the decision vectors."""
    bounds = space.certificate.delay_bounds
    batch = u.shape[0]
    if space.delays == "segments":
        values = u.reshape(batch, space.segments, 2)
        return tuple(PiecewiseDelay(times, values[..., c] * bounds[c], bounds[c])
                     for c in range(2))
    p = u.reshape(batch, 2, 4)
    slowest = 2.0
    half = space.control_period * (slowest / space.control_period) ** p[..., 2]
    return tuple(SquareWaveDelay(p[:, c, 0] * bounds[c], p[:, c, 1] * bounds[c], half[:, c],
                                 2.0 * half[:, c] * p[:, c, 3], bounds[c]) for c in range(2))


def _gain_points(space: SearchSpace, u: np.ndarray, layer: SafetyLayer) -> np.ndarray:
    """Gains ``(B, K, 2 n)`` from their block: bounding-box points projected on the polytope."""
    batch, n = u.shape[0], space.params.n_joints
    vertices = space.certificate.polytope.vertices()
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    raw = low + u.reshape(batch * space.gain_points, 2 * n) * (high - low)
    points = layer.project_batch(raw).action.reshape(batch, space.gain_points, 2 * n)
    return np.array(np.broadcast_to(points, (batch, space.segments, 2 * n)))


def decode(space: SearchSpace, x: np.ndarray, layer: SafetyLayer) -> Decision:
    """Map decision vectors in ``[0, 1]^d`` to adversarial choices.

    Parameters
    ----------
    space : SearchSpace
        The search space.
    x : ndarray, shape (B, d)
        Decision vectors (clipped to ``[0, 1]``).
    layer : SafetyLayer
        Projection onto the certificate's polytope.

    Returns
    -------
    Decision
        Switching times, gains, reference gains and delay profiles.
    """
    x = np.clip(np.atleast_2d(np.asarray(x, dtype=float)), 0.0, 1.0)
    if x.shape[1] != space.dimension:
        raise ValueError(f"decision vectors need {space.dimension} entries, got {x.shape[1]}")
    blocks = dict(zip(space.blocks, np.split(x, np.cumsum(list(space.blocks.values()))[:-1],
                                             axis=1), strict=True))
    batch, k = x.shape[0], space.segments
    switch = blocks["times"] if blocks["times"].shape[1] else np.linspace(0, 1, k + 1)[1:-1] \
        * np.ones((batch, 1))
    times = np.concatenate([np.zeros((batch, 1)), np.sort(switch, axis=1) * space.duration], 1)
    forward, backward = _delay_profiles(space, blocks["delays"], times)
    return Decision(times, _gain_points(space, blocks["gains"], layer),
                    2.0 * blocks["reference"] - 1.0, forward, backward)


def gain_schedule(space: SearchSpace, decision: Decision) -> np.ndarray:
    """Gains of every control period, shape ``(P, B, 2 n)``.

    Each period takes its segment's target; under a rate bound the gains move towards the target
    along the straight line (which stays in the convex polytope) by at most ``R T_s`` per
    coordinate and period, starting at the first target.

    Parameters
    ----------
    space : SearchSpace
        The search space.
    decision : Decision
        The adversarial choices.

    Returns
    -------
    ndarray, shape (P, B, 2 n)
        Gains held over each period.
    """
    periods = max(1, round(space.duration / space.control_period))
    starts = np.arange(periods) * space.control_period
    segment = np.sum(starts[:, None, None] >= decision.times[None] - 1e-12, axis=-1) - 1
    targets = np.take_along_axis(decision.gains[None], segment[..., None, None], axis=2)[:, :, 0]
    if math.isinf(space.rate):
        return np.ascontiguousarray(targets)
    step = space.rate * space.control_period
    out = np.empty_like(targets)
    current = targets[0].copy()
    for p in range(periods):
        move = targets[p] - current
        largest = np.abs(move).max(axis=-1, keepdims=True)
        current = current + move * np.minimum(1.0, step / np.maximum(largest, 1e-300))
        out[p] = current
    return out


def _simulate(space: SearchSpace, decision: Decision) -> Trajectory:
    """Run a batch of adversarial scenarios."""
    scenario = Scenario(space.params, decision.forward, decision.backward,
                        decision.reference_gains)
    sim = Simulator(scenario, space.dt, space.control_period)
    return sim.run(space.duration, gain_schedule(space, decision))


def _energy(params: TeleoperatorParams, trajectory: Trajectory) -> np.ndarray:
    """Mechanical energy of both arms, rotors and joint springs, shape ``(T, B)``."""
    layout, state = StateLayout(params.n_joints), trajectory.state
    blocks = (layout.get(state, name) for name in ("qr", "dqr", "theta", "dtheta"))
    with np.errstate(all="ignore"):
        return (kinetic_energy(params.local_arm, layout.get(state, "ql"),
                               layout.get(state, "dql"))
                + remote_energy(params.remote_arm, params.joints, *blocks))


def _growth(signal: np.ndarray) -> np.ndarray:
    """Log of the last-quarter peak over the second-quarter peak, per run."""
    quarter = max(1, signal.shape[0] // 4)
    with np.errstate(all="ignore"):
        late = np.log(signal[-quarter:].max(axis=0))
        return late - np.log(signal[quarter:2 * quarter].max(axis=0))


def _score(space: SearchSpace, trajectory: Trajectory, objective: str) -> pd.DataFrame:
    """Objective, growth ratios and divergence of every run of a batch."""
    state = trajectory.state
    finite = np.all(np.isfinite(state), axis=(0, 2))
    magnitude = position_magnitude(state[1:])
    energy = _energy(space.params, trajectory)
    error = (np.linalg.norm(trajectory.e_track, axis=-1)
             + np.linalg.norm(trajectory.e_damp, axis=-1))
    half = energy.shape[0] // 2
    with np.errstate(all="ignore"):
        values = {"energy_growth": _growth(energy), "error_growth": _growth(error),
                  "energy": np.log(energy[half:].max(axis=0))}
    verdict = Divergence(space.divergence_radius).assess(magnitude, finite, space.duration)
    table = pd.DataFrame({"objective": values[objective], "energy_growth": values["energy_growth"],
                          "error_growth": values["error_growth"], "growth": verdict["growth"],
                          "max_position": verdict["max_position"]})
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
    evaluations: int
    decision: Decision
    trajectory: pd.DataFrame
    history: pd.DataFrame = field(repr=False)
    search: str = "cma"

    @property
    def finding(self) -> bool:
        """A divergence inside what the certificate covers: it contradicts the certificate."""
        return self.diverged and self.covered

    def summary(self) -> str:
        """One line: what was searched and what the worst case did."""
        scope = "inside the certified class" if self.covered else "OUTSIDE the certified class"
        verdict = "DIVERGED" if self.diverged else "bounded"
        return (f"{self.method} ({self.gain_variation}), gains "
                f"{'switching' if self.switching else 'frozen'}, {self.delays} delays, {scope}: "
                f"worst {self.objective} "
                f"{self.value:.4g} after {self.evaluations} runs ({self.search}), {verdict}, "
                f"peak position {self.max_position:.3g} rad")

    def to_row(self) -> dict[str, Any]:
        """The scalar fields as one table row."""
        return {"method": self.method, "gain_variation": self.gain_variation,
                "switching": self.switching, "delays": self.delays, "covered": self.covered,
                "objective": self.objective, "value": self.value, "diverged": self.diverged,
                "energy_growth": self.energy_growth, "error_growth": self.error_growth,
                "growth": self.growth, "max_position": self.max_position,
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


def _check_search(budget: int, population: int, objective: str) -> None:
    for name, value in (("budget", budget), ("population", population)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 2:
            raise ValueError(f"{name} must be an integer >= 2, got {value!r}")
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")


def search(space: SearchSpace, objective: Objective = "energy_growth", method: Method = "cma",
           budget: int = 256, population: int = 16, seed: int = 0) -> SearchResult:
    """Search for the adversarial delays and gains that maximise ``objective``.

    Parameters
    ----------
    space : SearchSpace
        Teleoperator, certificate and adversary's freedom.
    objective : {"energy_growth", "error_growth", "energy"}
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
    _check_search(budget, population, objective)
    layer = SafetyLayer(space.certificate.polytope)
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
    trajectory = _simulate(space, decision)
    score = _score(space, trajectory, objective).iloc[0]
    return SearchResult(
        space.certificate.method, space.certificate.gain_variation, bool(space.switching),
        space.delays, space.covered, objective, float(score["objective"]), bool(score["diverged"]),
        float(score["energy_growth"]), float(score["error_growth"]), float(score["growth"]),
        float(score["max_position"]), len(history), decision, trajectory.to_frame(0),
        history[["generation", "objective", "diverged"]], method)
