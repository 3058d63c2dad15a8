r"""Gain controllers without learning: what a trained tuner is compared with.

A controller maps the observations of a batch of scenarios to raw gains ``[K_r..., B_r...]``
(the safety layer projects them, as it projects a policy's). Three kinds:

- :class:`ConstantGains`: the same gains at every step (fixed or best static gains);
- :class:`SemiActiveDamping`: a hand-written semi-active law in the spirit of semi-active
  suspensions (Karnopp et al. 1974): a constant common stiffness, and on each joint the high
  damping ``B_high`` while the spring deflection ``e_damp = theta_r - q_r`` grows in magnitude,
  the low damping ``B_low`` while it shrinks;
- :class:`GainSchedule`: gains as a function of time alone, replayed open loop (for example a
  tuner's mean schedule over training scenarios);

and :class:`HeldController`, which holds another controller's gains over several periods (a
tuner trained to decide every ``k`` control periods).

The last three keep state over an episode; :func:`~teleopkit.rl.evaluation.rollout` calls their
``reset()`` before the first step. Observations are read by the blocks of
:data:`~teleopkit.rl.scoring.OBSERVATION`; the run-time columns a scheduled class appends are
ignored.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from teleopkit.rl.scoring import OBSERVATION

__all__ = ["ConstantGains", "GainSchedule", "HeldController", "SemiActiveDamping"]

_DAMP = OBSERVATION.index("e_damp")


@dataclass(frozen=True)
class ConstantGains:
    """A controller that always asks for the same gains.

    Parameters
    ----------
    gains : ndarray, shape (2 n,)
        ``[K_r..., B_r...]``.
    """

    gains: np.ndarray

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The gains, once per observation row."""
        return np.tile(np.asarray(self.gains, dtype=float), (len(obs), 1))


@dataclass
class SemiActiveDamping:
    """High damping while each joint's spring deflection grows, low while it shrinks.

    The deflection's growth is read from two successive samples: joint ``i`` gets ``B_high``
    when ``|e_damp_i|`` grew over the last control period, else ``B_low`` (and ``B_low`` at the
    first step). The stiffness is constant, so under a scheduled class the law is covered with
    the storage never rising (no fall of ``kappa``). ``B_low`` belongs on or above the cone at
    ``K_r``: the safety layer projects a point below it to the nearest certified gains, which
    may lower the stiffness instead.

    Parameters
    ----------
    stiffness : float
        The common remote stiffness ``K_r`` of every joint.
    low, high : float
        The two damping levels ``B_low <= B_high``.
    """

    stiffness: float
    low: float
    high: float
    _last: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if not (0 <= self.low <= self.high and self.stiffness >= 0):
            raise ValueError(f"the semi-active law needs 0 <= B_low <= B_high and K_r >= 0, got "
                             f"K_r = {self.stiffness:g}, B_low = {self.low:g}, "
                             f"B_high = {self.high:g}")

    def reset(self) -> None:
        """Start an episode: no previous deflection."""
        self._last = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Gains for the observations of one control step, shape ``(B, 2 n)``."""
        obs = np.asarray(obs, dtype=float)
        n = (obs.shape[1] - obs.shape[1] % len(OBSERVATION)) // len(OBSERVATION)
        deflection = np.abs(obs[:, _DAMP * n:(_DAMP + 1) * n])
        growing = (np.zeros_like(deflection, dtype=bool) if self._last is None
                   or self._last.shape != deflection.shape else deflection > self._last)
        self._last = deflection
        damping = np.where(growing, self.high, self.low)
        return np.concatenate([np.full_like(damping, self.stiffness), damping], axis=1)


@dataclass
class GainSchedule:
    """Gains as a function of the control step alone, replayed open loop.

    Parameters
    ----------
    gains : ndarray, shape (P, 2 n)
        The gains of each control period; after the last one, the last is held.
    """

    gains: np.ndarray
    _step: int = field(default=0, init=False, repr=False)

    def __post_init__(self) -> None:
        self.gains = np.asarray(self.gains, dtype=float)
        if self.gains.ndim != 2 or len(self.gains) == 0 or not np.all(np.isfinite(self.gains)):
            raise ValueError("a gain schedule needs finite gains of shape (periods, 2 n)")

    def reset(self) -> None:
        """Start an episode at the first period."""
        self._step = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The gains of the current period for every scenario, shape ``(B, 2 n)``."""
        row = self.gains[min(self._step, len(self.gains) - 1)]
        self._step += 1
        return np.tile(row, (len(obs), 1))


@dataclass
class HeldController:
    """Another controller asked every ``periods`` control periods, its gains held in between.

    Parameters
    ----------
    controller : callable
        Observations ``(B, obs_dim)`` to raw gains ``(B, 2 n)`` (a reset() is passed on).
    periods : int
        Control periods per decision.
    """

    controller: Callable[[np.ndarray], np.ndarray]
    periods: int
    _count: int = field(default=0, init=False, repr=False)
    _gains: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.periods < 1:
            raise ValueError(f"a held controller decides every periods >= 1, got {self.periods}")

    def reset(self) -> None:
        """Start an episode: the next call asks the controller."""
        self._count = 0
        reset = getattr(self.controller, "reset", None)
        if callable(reset):
            reset()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The controller's gains at a decision, else the gains held since the last one."""
        if self._gains is None or self._count % self.periods == 0:
            self._gains = np.asarray(self.controller(obs), dtype=float)
        self._count += 1
        return self._gains
