"""Combinators of delay profiles: scaling and stacking per-scenario profiles into a batch.

The simulator takes one forward and one backward :class:`~teleopkit.delays.DelayProfile` for a
whole batch. Campaigns and the falsification search build one profile per scenario;
:func:`stack_delays` turns them into one batch profile (merging the paper's Fourier profiles and
constant delays into single vectorised profiles) and :func:`scale_delay` multiplies a profile and
its bound by a factor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from teleopkit.delays.jumps import has_jumps, sample_left
from teleopkit.delays.profiles import (
    ConstantDelay,
    DelayProfile,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
    delay_floor,
)

__all__ = ["ScaledDelay", "StackedDelay", "scale_delay", "stack_delays"]


def _width(profile: DelayProfile) -> int:
    """Batch size of a profile (columns of its samples)."""
    return int(profile.sample(np.zeros(1)).shape[1])


@dataclass(frozen=True)
class ScaledDelay:
    """A profile multiplied by a constant factor.

    :func:`scale_delay` uses it for profiles without a closed-form scaled version.

    Parameters
    ----------
    profile : DelayProfile
        The profile to scale.
    factor : float
        Non-negative finite factor.
    """

    profile: DelayProfile
    factor: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.factor) and self.factor >= 0):
            raise ValueError(f"delay scale must be finite and >= 0, got {self.factor}")

    @property
    def bound(self) -> float:
        """Declared bound: the profile's bound times the factor."""
        return float(self.profile.bound) * self.factor

    @property
    def floor(self) -> float:
        """Declared lower bound: the profile's floor times the factor."""
        return delay_floor(self.profile) * self.factor

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the scaled delays at the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds.
        """
        return self.factor * self.profile.sample(t)

    @property
    def jumps(self) -> bool:
        """Whether the profile jumps (:mod:`teleopkit.delays.jumps`)."""
        return has_jumps(self.profile)

    def sample_left(self, t: np.ndarray) -> np.ndarray:
        """Return the scaled delays just before the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds.
        """
        return self.factor * sample_left(self.profile, t)


def scale_delay(profile: DelayProfile, factor: float) -> DelayProfile:
    """Multiply a delay profile and its declared bound by ``factor``.

    Parameters
    ----------
    profile : DelayProfile
        The profile.
    factor : float
        Non-negative finite factor (1 returns ``profile`` itself).

    Returns
    -------
    DelayProfile
        A profile of the same class when it has a closed form (Fourier, constant, sinusoidal,
        switching, trace), else a :class:`ScaledDelay`.
    """
    if not (math.isfinite(factor) and factor >= 0):
        raise ValueError(f"delay scale must be finite and >= 0, got {factor}")
    if factor == 1.0:
        return profile
    if isinstance(profile, FourierDelay):
        return FourierDelay(factor * np.asarray(profile.scale), factor * profile.bound)
    if isinstance(profile, ConstantDelay):
        return ConstantDelay(factor * np.asarray(profile.value), factor * profile.bound)
    if isinstance(profile, SinusoidalDelay):
        return replace(profile, mean=factor * profile.mean, amplitude=factor * profile.amplitude)
    if isinstance(profile, SwitchingDelay):
        return replace(profile, low=factor * profile.low, high=factor * profile.high)
    if isinstance(profile, TraceDelay):
        return TraceDelay(profile.times, factor * profile.delays, factor * profile.bound)
    return ScaledDelay(profile, factor)


@dataclass(frozen=True)
class StackedDelay:
    """Several profiles side by side on the batch axis.

    Parameters
    ----------
    parts : tuple of DelayProfile
        Profiles whose batches are concatenated (each checks its own bound).
    order : tuple of int, optional
        Column permutation applied after concatenation (``out = concat[:, order]``); identity by
        default.

    Notes
    -----
    A part that appears several times (the same object, for example one drawn profile shared
    by many scenarios) is sampled once per call and its columns repeated.
    """

    parts: tuple[DelayProfile, ...]
    order: tuple[int, ...] = ()
    _distinct: tuple[DelayProfile, ...] = field(init=False, repr=False, compare=False)
    _gather: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.parts:
            raise ValueError("a stacked delay needs at least one profile")
        object.__setattr__(self, "parts", tuple(self.parts))
        distinct: dict[int, tuple[DelayProfile, int, int]] = {}  # id -> part, first, width
        columns: list[np.ndarray] = []
        start = 0
        for part in self.parts:
            if id(part) not in distinct:
                distinct[id(part)] = (part, start, _width(part))
                start += distinct[id(part)][2]
            _, first, width = distinct[id(part)]
            columns.append(np.arange(first, first + width))
        gather = np.concatenate(columns)
        order = tuple(int(i) for i in self.order) or tuple(range(gather.size))
        if sorted(order) != list(range(gather.size)):
            raise ValueError(f"stacked delay order must be a permutation of range({gather.size})")
        object.__setattr__(self, "order", order)
        object.__setattr__(self, "_distinct", tuple(part for part, _, _ in distinct.values()))
        object.__setattr__(self, "_gather", gather[list(order)])

    @property
    def bound(self) -> float:
        """Declared bound: the largest of the parts' bounds."""
        return max(float(part.bound) for part in self.parts)

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest of the parts' floors."""
        return min(delay_floor(part) for part in self.parts)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds, ``B`` the total batch of the parts.
        """
        return self._joined([part.sample(t) for part in self._distinct])

    @property
    def jumps(self) -> bool:
        """Whether some part jumps (:mod:`teleopkit.delays.jumps`)."""
        return any(has_jumps(part) for part in self.parts)

    def sample_left(self, t: np.ndarray) -> np.ndarray:
        """Return the delays just before the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds, ``B`` the total batch of the parts.
        """
        return self._joined([sample_left(part, t) for part in self._distinct])

    def _joined(self, values: list[np.ndarray]) -> np.ndarray:
        """The distinct parts' samples, columns repeated for every appearance, in :attr:`order`."""
        return np.concatenate(values, axis=1)[:, self._gather]


def _merge(kind: type, members: list[DelayProfile]) -> DelayProfile:
    """One vectorised profile for several Fourier or constant profiles of batch 1."""
    bound = max(float(p.bound) for p in members)
    if kind is FourierDelay:
        scales = np.concatenate([np.atleast_1d(p.scale) for p in members])  # type: ignore[attr-defined]
        return FourierDelay(scales, bound)
    values = np.concatenate([np.atleast_1d(p.value) for p in members])  # type: ignore[attr-defined]
    return ConstantDelay(values, bound)


def stack_delays(profiles: Sequence[DelayProfile]) -> DelayProfile:
    """One batch profile from one profile per scenario (in that order).

    Fourier and constant profiles are merged into one vectorised profile of each class (their
    values are unchanged; the merged profile checks the largest of their bounds, which each of
    their values satisfies by construction); the others are stacked as they are.

    Parameters
    ----------
    profiles : sequence of DelayProfile
        One profile of batch 1 per scenario.

    Returns
    -------
    DelayProfile
        The profile itself for one scenario, else a :class:`StackedDelay`.
    """
    if len(profiles) == 1:
        return profiles[0]
    groups: dict[type, list[int]] = {}
    for index, profile in enumerate(profiles):
        kind: type = type(profile) if isinstance(profile, FourierDelay | ConstantDelay) else object
        groups.setdefault(kind, []).append(index)
    parts: list[DelayProfile] = []
    columns: list[int] = []
    for kind, indices in groups.items():
        members = [profiles[i] for i in indices]
        parts.extend([_merge(kind, members)] if kind is not object else members)
        columns.extend(indices)
    order = np.argsort(columns)
    return StackedDelay(tuple(parts), tuple(int(i) for i in order))
