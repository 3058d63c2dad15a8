"""Combinators of delay profiles: scaling, stacking per-scenario profiles, piecewise constants.

The simulator takes one forward and one backward :class:`~teleopkit.delays.DelayProfile` for a
whole batch. Campaigns and the falsification search build one profile per scenario;
:func:`stack_delays` turns them into one batch profile (merging the paper's Fourier profiles and
constant delays into single vectorised profiles), :func:`scale_delay` multiplies a profile and its
bound by a factor, :class:`PiecewiseDelay` holds per-scenario values between switching times and
:class:`SquareWaveDelay` switches per scenario between two values at a fixed rate (what an
adversary chooses).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from teleopkit.delays import (
    ConstantDelay,
    DelayProfile,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
)

__all__ = [
    "PiecewiseDelay",
    "ScaledDelay",
    "SquareWaveDelay",
    "StackedDelay",
    "scale_delay",
    "stack_delays",
]


def _width(profile: DelayProfile) -> int:
    """Batch size of a profile (columns of its samples)."""
    return int(profile.sample(np.zeros(1)).shape[1])


def _checked_bound(values: np.ndarray, bound: float, kind: str) -> float:
    """The delay bound (``max(values)`` when ``bound`` is NaN); every value must lie below it."""
    bound = float(values.max()) if math.isnan(bound) else float(bound)
    if values.min() < 0 or values.max() > bound:
        raise ValueError(f"{kind} delay values must lie in [0, {bound:g}]")
    return bound


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
    """

    parts: tuple[DelayProfile, ...]
    order: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not self.parts:
            raise ValueError("a stacked delay needs at least one profile")
        object.__setattr__(self, "parts", tuple(self.parts))
        width = sum(_width(part) for part in self.parts)
        order = tuple(int(i) for i in self.order) or tuple(range(width))
        if sorted(order) != list(range(width)):
            raise ValueError(f"stacked delay order must be a permutation of range({width})")
        object.__setattr__(self, "order", order)

    @property
    def bound(self) -> float:
        """Declared bound: the largest of the parts' bounds."""
        return max(float(part.bound) for part in self.parts)

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
        values = np.concatenate([part.sample(t) for part in self.parts], axis=1)
        return values[:, list(self.order)]


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


@dataclass(frozen=True)
class PiecewiseDelay:
    """Per-scenario delays, constant between switching times.

    Scenario ``b`` has the delay ``values[b, k]`` on ``[times[b, k], times[b, k + 1])`` (the last
    value holds forever; before ``times[b, 0]`` the first value holds).

    Parameters
    ----------
    times : ndarray, shape (B, K)
        Switching times in seconds, non-decreasing along each row.
    values : ndarray, shape (B, K)
        Delay on each segment in seconds, in ``[0, bound]``.
    bound : float, optional
        Declared bound; the largest value by default.
    """

    times: np.ndarray
    values: np.ndarray
    bound: float = math.nan

    def __post_init__(self) -> None:
        times = np.atleast_2d(np.asarray(self.times, dtype=float))
        values = np.atleast_2d(np.asarray(self.values, dtype=float))
        if times.shape != values.shape or times.shape[1] == 0:
            raise ValueError(f"piecewise delay needs times and values of one shape (B, K), got "
                             f"{times.shape} and {values.shape}")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values))):
            raise ValueError("piecewise delay times and values must be finite")
        if np.any(np.diff(times, axis=1) < 0):
            raise ValueError("piecewise delay switching times must be non-decreasing")
        bound = _checked_bound(values, self.bound, "piecewise")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "bound", bound)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        segment = np.sum(t[:, None, None] >= self.times[None], axis=-1) - 1
        segment = np.clip(segment, 0, self.times.shape[1] - 1)
        return np.take_along_axis(self.values.T, segment, axis=0)


@dataclass(frozen=True)
class SquareWaveDelay:
    """Per-scenario delays switching between ``low`` and ``high`` every ``half_period`` seconds.

    Scenario ``b`` holds ``low[b]`` on ``[2 k h - phase, (2 k + 1) h - phase)`` and ``high[b]``
    on the other half periods (``h = half_period[b]``): the bang-bang delay of adversarial
    tests, as fast as ``h`` allows.

    Parameters
    ----------
    low, high : ndarray, shape (B,)
        The two delays in seconds, in ``[0, bound]``.
    half_period : ndarray, shape (B,)
        Time between switches in seconds (positive).
    phase : ndarray, shape (B,)
        Time shift in seconds.
    bound : float, optional
        Declared bound; the largest value by default.
    """

    low: np.ndarray
    high: np.ndarray
    half_period: np.ndarray
    phase: np.ndarray
    bound: float = math.nan

    def __post_init__(self) -> None:
        arrays = [np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
                  for name in ("low", "high", "half_period", "phase")]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise ValueError("square-wave delay needs low, high, half_period and phase of one "
                             "shape (B,)")
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError("square-wave delay parameters must be finite")
        if np.any(arrays[2] <= 0):
            raise ValueError("square-wave delay half period must be positive")
        values = np.concatenate(arrays[:2])
        bound = _checked_bound(values, self.bound, "square-wave")
        for name, array in zip(("low", "high", "half_period", "phase"), arrays, strict=True):
            object.__setattr__(self, name, array)
        object.__setattr__(self, "bound", bound)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``, shape ``(S, B)``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delays in seconds.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
        odd = np.floor((t + self.phase) / self.half_period + 1e-9) % 2 == 1
        return np.where(odd, self.high, self.low)
