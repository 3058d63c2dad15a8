"""The adversary of a falsification search: what it may choose, and its choices decoded.

A :class:`SearchSpace` is derived from a certificate: delays within its bounds (square waves or
piecewise constants), remote gains inside its polytope (one point per run for frozen gains, one
per segment otherwise, moving at the certified rate for ``rate:R``) and the operator's reference
gains. A decision vector in ``[0, 1]^d`` decodes into a :class:`Decision`;
:func:`gain_schedule` turns it into the gains of every control period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation
from teleopkit.delays.adversarial import PiecewiseDelay, SquareWaveDelay
from teleopkit.model.params import TeleoperatorParams
from teleopkit.safety.factory import layer_for
from teleopkit.safety.layer import SafetyLayer
from teleopkit.safety.polytope import PolytopeLayer
from teleopkit.sim.divergence import DIVERGENCE_RADIUS
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT
from teleopkit.sim.timing import periods as whole_periods

__all__ = ["Decision", "SearchSpace", "decode", "gain_schedule"]


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
        Seconds per run, a whole number of control periods.
    dt : float
        Integration step.
    control_period : float
        Gain hold period.
    divergence_radius : float
        Position magnitude (rad) that counts as divergence.
    controller : callable, optional
        A gain controller (for example a trained policy,
        :class:`~teleopkit.rl.policy.GainPolicy`) that picks the gains in closed loop through
        the certificate's safety layer; the adversary then chooses the delays only.
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
    controller: Any = None

    def __post_init__(self) -> None:
        if self.certificate.box.n_joints != self.params.n_joints:
            raise ValueError(f"certificate has {self.certificate.box.n_joints} joints, the "
                             f"teleoperator {self.params.n_joints}")
        if self.certificate.polytope.is_empty():
            raise ValueError("the certificate's gain polytope is empty: nothing to search")
        if isinstance(self.segments, bool) or not isinstance(self.segments, int) or \
                self.segments < 1:
            raise ValueError(f"segments must be an integer >= 1, got {self.segments!r}")
        whole_periods(self.duration, self.control_period)
        if self.delays not in ("square", "segments"):
            raise ValueError(f"delays must be 'square' or 'segments', got {self.delays!r}")
        if self.switching is None or self.controller is not None:
            object.__setattr__(self, "switching", self.variation.covers_changes)
        if self.variation.scheduled:  # the plant as the storage's proof assumes it
            n = self.params.n_joints
            passive = replace(self.params.operator, amplitudes=(0.0,) * n)
            object.__setattr__(self, "params", replace(self.params, operator=passive,
                                                       torque_limit=math.inf))

    @property
    def variation(self) -> GainVariation:
        """The certificate's :class:`~teleopkit.certification.GainVariation`."""
        return parse_gain_variation(self.certificate.gain_variation)

    @property
    def covered(self) -> bool:
        """Whether every run of the space lies within what the certificate covers."""
        frozen_only = self.variation.kind == "frozen"
        changes = self.switching or self.controller is not None
        return bool(self.certificate.polytope_certified and not (changes and frozen_only))

    @property
    def rate(self) -> float:
        """Largest gain rate (per second) of a rate-bounded certificate, else ``inf``."""
        variation = self.variation
        return float(variation.rate) if variation.kind == "rate" else math.inf

    @property
    def gain_points(self) -> int:
        """Gain points per run: one per segment when switching, else one; none with a controller."""
        if self.controller is not None:
            return 0
        return self.segments if self.switching else 1

    @property
    def blocks(self) -> dict[str, int]:
        """Lengths of the parts of a decision vector, in order."""
        n, k = self.params.n_joints, self.segments
        uses_times = ((self.switching and self.controller is None)
                      or self.delays == "segments")
        return {"times": k - 1 if uses_times else 0,
                "delays": 2 * k if self.delays == "segments" else 8,
                "gains": 2 * n * self.gain_points,
                "reference": 0 if self.variation.scheduled else n}

    @property
    def storage_bound(self) -> float:
        """The proven bound of ``storage_ratio``: ``exp(L)``, 1 with a tank, NaN otherwise."""
        variation = self.variation
        if not variation.scheduled:
            return math.nan
        return math.exp(variation.value) if variation.kind == "scheduled" else 1.0

    def layer(self) -> SafetyLayer:
        """The projection the gains go through: the class's own layer (scheduled, controller)."""
        if self.variation.scheduled or self.controller is not None:
            return layer_for(self.certificate, self.control_period)
        return PolytopeLayer(self.certificate.polytope)

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
    """Gains ``(B, K, 2 n)``: bounding-box points projected (none when a controller picks)."""
    batch, n = u.shape[0], space.params.n_joints
    if space.controller is not None:
        return np.zeros((batch, 0, 2 * n))
    vertices = space.certificate.polytope.vertices()
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    raw = low + u.reshape(batch * space.gain_points, 2 * n) * (high - low)
    points = layer.project_set(raw).reshape(batch, space.gain_points, 2 * n)
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
    reference = (2.0 * blocks["reference"] - 1.0 if blocks["reference"].shape[1]
                 else np.zeros((batch, space.params.n_joints)))
    return Decision(times, _gain_points(space, blocks["gains"], layer), reference, forward,
                    backward)


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
