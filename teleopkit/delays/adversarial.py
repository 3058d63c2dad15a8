"""Adversarial delay profiles: per-scenario piecewise constants and fast square waves.

:class:`PiecewiseDelay` holds per-scenario values between switching times and
:class:`SquareWaveDelay` switches per scenario between two values at a fixed rate: the delays a
falsification search chooses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from teleopkit.delays.profiles import check_delays, declared_bound

__all__ = ["PiecewiseDelay", "SquareWaveDelay"]

_AT = 1e-9
"""Seconds within which a time is at a switching time: times on a step grid carry rounding."""


@dataclass(frozen=True)
class PiecewiseDelay:
    """Per-scenario delays, constant between switching times.

    Scenario ``b`` has the delay ``values[b, k]`` on ``[times[b, k], times[b, k + 1])`` (the last
    value holds forever; before ``times[b, 0]`` the first value holds); a time within a
    nanosecond of a switching time is at it.

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
    jumps = True
    """It is constant between switches (:mod:`teleopkit.delays.jumps`)."""

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
        bound = declared_bound(values, self.bound)
        check_delays("piecewise delay", values, bound)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "bound", bound)

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest value."""
        return float(self.values.min())

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
        return self._on(np.sum(t[:, None, None] + _AT >= self.times[None], axis=-1) - 1)

    def sample_left(self, t: np.ndarray) -> np.ndarray:
        """Return the delays just before the times ``t`` (at a switch: the old value).

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
        return self._on(np.sum(t[:, None, None] - _AT > self.times[None], axis=-1) - 1)

    def _on(self, segment: np.ndarray) -> np.ndarray:
        """The values of the segments ``segment`` ``(S, B)`` (before the first: the first)."""
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
    jumps = True
    """It is constant between switches (:mod:`teleopkit.delays.jumps`)."""

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
        bound = declared_bound(values, self.bound)
        check_delays("square-wave delay", values, bound)
        for name, array in zip(("low", "high", "half_period", "phase"), arrays, strict=True):
            object.__setattr__(self, name, array)
        object.__setattr__(self, "bound", bound)

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest of the two delays."""
        return float(min(self.low.min(), self.high.min()))

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
        return self._on(np.floor((t + self.phase) / self.half_period + 1e-9))

    def sample_left(self, t: np.ndarray) -> np.ndarray:
        """Return the delays just before the times ``t`` (at a switch: the old value).

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
        return self._on(np.ceil((t + self.phase) / self.half_period - 1e-9) - 1)

    def _on(self, half: np.ndarray) -> np.ndarray:
        """The delays on the half periods ``half`` ``(S, B)`` (even: low, odd: high)."""
        return np.where(half % 2 == 1, self.high, self.low)
