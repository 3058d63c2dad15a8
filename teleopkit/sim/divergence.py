"""When a simulated run counts as diverged: the one criterion of campaigns and falsification.

A run is *diverged* when

* its state becomes non-finite, or
* a position (local arm, remote link or motor angle) exceeds the divergence radius, or
* its motion grows: ``growth``, the peak position magnitude over the last quarter of the run
  over that of the second quarter, exceeds 1 while the last-quarter peak exceeds
  :data:`GROWTH_FLOOR`, in a run of at least :data:`GROWTH_MIN_DURATION`.

The operator's reference decays, so a stable run shrinks; a shorter run is mostly its initial
transient, and below the floor the ratio measures numerical noise, not motion.

The first two tests happen at a time (:meth:`Divergence.onset`): :func:`teleopkit.simulate`
warns with a :class:`DivergenceWarning` naming it, and ``teleopkit simulate`` exits with 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from teleopkit.sim.state import StateLayout

__all__ = ["DIVERGENCE_RADIUS", "GROWTH_FLOOR", "GROWTH_MIN_DURATION", "Divergence",
           "DivergenceWarning", "position_magnitude"]

DIVERGENCE_RADIUS = 20.0
"""Default position magnitude (rad) that counts as divergence."""

GROWTH_FLOOR = 0.01
"""Smallest last-quarter peak position (rad) at which a growth above 1 counts as divergence."""

GROWTH_MIN_DURATION = 10.0
"""Shortest run (s) whose growth counts as divergence (shorter runs are mostly transient)."""


def position_magnitude(state: np.ndarray) -> np.ndarray:
    """Largest absolute joint angle of each state (``inf`` for a non-finite state).

    Parameters
    ----------
    state : ndarray, shape (..., 12 n)
        States (:class:`~teleopkit.sim.state.StateLayout`).

    Returns
    -------
    ndarray, shape (...)
        ``max |q|`` over the local, remote link and motor angles.
    """
    positions = np.abs(state[..., StateLayout.of(state).positions])
    return np.nan_to_num(positions, nan=np.inf).max(axis=-1)


class DivergenceWarning(RuntimeWarning):
    """A simulated run diverged: its state stopped being finite or left the divergence radius."""


@dataclass(frozen=True)
class Divergence:
    """The divergence criterion (see the module docstring).

    Parameters
    ----------
    radius : float
        Position magnitude (rad) that counts as divergence.
    growth_floor : float
        Smallest last-quarter peak (rad) at which growth counts.
    min_duration : float
        Shortest run (s) whose growth counts.
    """

    radius: float = DIVERGENCE_RADIUS
    growth_floor: float = GROWTH_FLOOR
    min_duration: float = GROWTH_MIN_DURATION

    def __post_init__(self) -> None:
        for name in ("radius", "growth_floor", "min_duration"):
            value = float(getattr(self, name))
            if not (np.isfinite(value) and value >= 0) or (name == "radius" and value == 0):
                raise ValueError(f"divergence {name} must be finite and positive, got {value}")

    def assess(self, magnitude: np.ndarray, finite: np.ndarray,
               duration: float) -> dict[str, np.ndarray]:
        """Peak position, growth ratio and verdict of each run.

        Parameters
        ----------
        magnitude : ndarray, shape (P, B)
            :func:`position_magnitude` at each recorded time after ``t = 0``.
        finite : ndarray of bool, shape (B,)
            Whether each run's state stayed finite.
        duration : float
            Length of the runs in seconds.

        Returns
        -------
        dict of str to ndarray, shape (B,)
            ``max_position``, ``growth`` (last-quarter over second-quarter peak) and
            ``diverged``.
        """
        quarter = max(1, magnitude.shape[0] // 4)
        late = magnitude[-quarter:].max(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            growth = late / magnitude[quarter:2 * quarter].max(axis=0)
        peak = magnitude.max(axis=0)
        growing = (growth > 1.0) & (late > self.growth_floor) & (duration >= self.min_duration)
        return {"max_position": peak, "growth": growth,
                "diverged": ~np.asarray(finite) | (peak > self.radius) | growing}

    def onset(self, t: np.ndarray, state: np.ndarray) -> np.ndarray:
        """When each run first stopped being finite or had a position beyond the radius.

        Parameters
        ----------
        t : ndarray, shape (P,)
            Recorded times in seconds.
        state : ndarray, shape (P, B, 12 n)
            States at those times (:class:`~teleopkit.sim.state.StateLayout`).

        Returns
        -------
        ndarray, shape (B,)
            The first such time of each run, NaN for a run that never diverged so (growth, the
            third test, is a verdict on a whole run: :meth:`assess`).
        """
        gone = (position_magnitude(state) > self.radius) | ~np.all(np.isfinite(state), axis=-1)
        return np.where(gone.any(axis=0), np.asarray(t)[gone.argmax(axis=0)], np.nan)

    def describe(self, t: np.ndarray, state: np.ndarray, scenario: int = 0) -> str | None:
        """One line saying when and how run ``scenario`` diverged (:meth:`onset`), or None.

        Parameters
        ----------
        t, state
            As for :meth:`onset`.
        scenario : int
            Index of the run in the batch.

        Returns
        -------
        str or None
            ``"the run diverged at t = ... s: ..."``; None if it did not.
        """
        at = self.onset(t, state[:, scenario:scenario + 1])[0]
        if np.isnan(at):
            return None
        row = int(np.searchsorted(t, at))
        how = ("its state stopped being finite" if not np.all(np.isfinite(state[row, scenario]))
               else f"a position passed {self.radius:g} rad")
        return f"the run diverged at t = {at:g} s: {how}"
