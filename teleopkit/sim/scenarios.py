"""Scenarios: a teleoperator, its two delay profiles and the operator's per-episode reference gains.

:func:`paper_scenarios` draws the randomisation of the authors' simulation model: reference
gains ``G_i`` uniform on ``[-1, -0.5] U [0.5, 1]`` and delay scales ``g_m, g_s ~ U[0.5, 1]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from teleopkit.delays.paper_fit import PAPER_DELAY_MAX, PAPER_DELAY_MIN
from teleopkit.delays.profiles import ConstantDelay, DelayProfile, FourierDelay
from teleopkit.model.params import TeleoperatorParams, paper_setup

__all__ = ["PAPER_DELAY_BOUND", "PAPER_DELAY_FLOOR", "PAPER_SCALES", "Scenario", "paper_scenarios",
           "sample_reference_gains"]

PAPER_SCALES = (0.5, 1.0)
"""Range of the per-episode delay scales ``g_m, g_s`` of :func:`paper_scenarios`."""

PAPER_DELAY_BOUND = PAPER_SCALES[1]
"""Largest delay of :func:`paper_scenarios` in seconds: the scale times the Fourier profile,
which :class:`~teleopkit.delays.profiles.FourierDelay` keeps within 1 s."""

PAPER_DELAY_FLOOR = PAPER_SCALES[0] * PAPER_DELAY_MIN / PAPER_DELAY_MAX
"""Smallest delay of :func:`paper_scenarios` in seconds (about 0.451 s): the smallest scale
times the Fourier profile's rigorous minimum. A certificate for delays from at most this
minimum covers the paper's scenarios."""


@dataclass(frozen=True)
class Scenario:
    """A batch of ``B`` scenarios sharing one teleoperator.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    forward : DelayProfile
        Local-to-remote delay ``T_l(t)`` (batch 1 or ``B``).
    backward : DelayProfile
        Remote-to-local delay ``T_r(t)`` (batch 1 or ``B``).
    reference_gains : ndarray, shape (B, n)
        Operator reference gains ``G`` of each scenario.
    """

    params: TeleoperatorParams = field(default_factory=paper_setup)
    forward: DelayProfile = field(default_factory=ConstantDelay)
    backward: DelayProfile = field(default_factory=ConstantDelay)
    reference_gains: np.ndarray = field(default_factory=lambda: np.ones((1, 2)))

    def __post_init__(self) -> None:
        gains = np.atleast_2d(np.asarray(self.reference_gains, dtype=float))
        if gains.ndim != 2 or gains.shape[1] != self.params.n_joints:
            raise ValueError(f"reference gains need shape (batch, {self.params.n_joints}), "
                             f"got {gains.shape}")
        if not np.all(np.isfinite(gains)):
            raise ValueError("reference gains must be finite")
        object.__setattr__(self, "reference_gains", gains)
        for name in ("forward", "backward"):
            profile = getattr(self, name)
            bound = profile.bound
            if not np.isfinite(bound) or bound < 0:
                raise ValueError(f"{name} delay bound must be finite and >= 0, got {bound}")
            columns = np.shape(profile.sample(np.zeros(1)))[-1]
            if columns not in (1, gains.shape[0]):
                raise ValueError(f"the {name} delay profile has {columns} scenarios, the "
                                 f"reference gains {gains.shape[0]}: give it 1 or the same")

    @property
    def batch(self) -> int:
        """Number of scenarios."""
        return self.reference_gains.shape[0]

    @property
    def delay_bound(self) -> float:
        """Largest delay of either channel."""
        return max(self.forward.bound, self.backward.bound)


def sample_reference_gains(rng: np.random.Generator, batch: int, n_joints: int = 2) -> np.ndarray:
    """Draw reference gains uniformly on ``[-1, -0.5] U [0.5, 1]``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the magnitudes and signs.
    batch : int
        Number of scenarios.
    n_joints : int
        Number of joints.

    Returns
    -------
    ndarray, shape (batch, n_joints)
        Operator reference gains ``G``: magnitudes from ``U[0.5, 1]``, each sign negative with
        probability 1/2.
    """
    magnitude = rng.uniform(0.5, 1.0, size=(batch, n_joints))
    return np.where(rng.random((batch, n_joints)) < 0.5, -magnitude, magnitude)


def paper_scenarios(rng: np.random.Generator | int = 0, batch: int = 1,
                    params: TeleoperatorParams | None = None) -> Scenario:
    """Draw ``batch`` scenarios with the paper's randomisation.

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Generator or seed.
    batch : int
        Number of scenarios.
    params : TeleoperatorParams, optional
        Teleoperator; the paper's by default.

    Returns
    -------
    Scenario
        Fourier delays scaled by ``U[0.5, 1]`` per channel and random reference gains.

    Examples
    --------
    >>> scenario = paper_scenarios(0, batch=4)
    >>> scenario.batch, bool(round(scenario.delay_bound, 3) <= 1.001)
    (4, True)
    """
    if isinstance(batch, bool) or not isinstance(batch, int | np.integer) or batch < 1:
        raise ValueError(f"batch must be a whole number of scenarios >= 1, got {batch!r}")
    rng = np.random.default_rng(rng)
    params = params if params is not None else paper_setup()
    reference = sample_reference_gains(rng, batch, params.n_joints)
    scales = rng.uniform(*PAPER_SCALES, size=(2, batch))
    return Scenario(params, FourierDelay(scales[0]), FourierDelay(scales[1]), reference)
