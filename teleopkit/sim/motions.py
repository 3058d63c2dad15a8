"""Operator reference motions ``q_h(t)``: sums of (decaying) sines and recorded motions.

A motion is sampled at the simulator's stage times and returns one column per scenario, or one
column shared by a whole batch (the simulator then scales it by each scenario's reference
gains, see :class:`~teleopkit.sim.scenarios.Scenario`). The paper's operator is one decaying
sine per joint, ``q_h,i = A_i sin(w_i t + phi_i) exp(-d_i t)``
(:meth:`SineMotion.from_operator`); random smooth motions are sums of a few sines per joint
with drawn amplitudes, frequencies and phases (:func:`smooth_motions`); a recorded hand motion
is a table of times and joint angles (:meth:`RecordedMotion.from_csv`), which must last as long
as the run it drives (:func:`check_motion_ends`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from teleopkit.model.params import Operator

__all__ = ["Motion", "RecordedMotion", "SineMotion", "check_motion_ends", "smooth_motions"]


@runtime_checkable
class Motion(Protocol):
    """What the simulator needs of an operator reference motion."""

    @property
    def columns(self) -> int:
        """Scenarios it describes: 1 (shared by a batch) or one per scenario."""

    @property
    def n_joints(self) -> int:
        """Joints it moves."""

    def sample(self, times: np.ndarray) -> np.ndarray:
        """Reference joint angles at some times.

        Parameters
        ----------
        times : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, columns, n)
            ``q_h`` in radians.
        """


@dataclass(frozen=True, eq=False)
class SineMotion:
    """Sums of decaying sines, ``q_h,i(t) = sum_c A_ci sin(w_ci t + phi_ci) exp(-d_ci t)``.

    Parameters
    ----------
    amplitudes, frequencies, phases, decays : ndarray, shape (K, C, n)
        Per scenario (``K``: 1 or the batch), component (``C``) and joint: amplitude (rad),
        angular frequency (rad/s), phase (rad) and decay rate (1/s, zero for a motion that
        never dies out). Shapes broadcast against each other.
    """

    amplitudes: np.ndarray
    frequencies: np.ndarray
    phases: np.ndarray
    decays: np.ndarray

    def __post_init__(self) -> None:
        arrays = np.broadcast_arrays(*(np.asarray(getattr(self, name), dtype=float) for name in (
            "amplitudes", "frequencies", "phases", "decays")))
        if arrays[0].ndim != 3 or 0 in arrays[0].shape:
            raise ValueError("sine motion parameters need shape (scenarios, components, joints), "
                             f"got {arrays[0].shape}")
        for name, array in zip(("amplitudes", "frequencies", "phases", "decays"), arrays,
                               strict=True):
            if not np.all(np.isfinite(array)):
                raise ValueError(f"sine motion {name} must be finite")
            object.__setattr__(self, name, np.array(array))

    @classmethod
    def from_operator(cls, operator: Operator) -> SineMotion:
        """The operator's reference with unit gains: one decaying sine per joint.

        Parameters
        ----------
        operator : Operator
            Its ``amplitudes``, ``frequencies``, ``phases`` and ``decays``.

        Returns
        -------
        SineMotion
            One column, one component.
        """
        return cls(*(np.array(getattr(operator, name))[None, None] for name in (
            "amplitudes", "frequencies", "phases", "decays")))

    @property
    def columns(self) -> int:
        """Scenarios it describes (1: shared)."""
        return int(self.amplitudes.shape[0])

    @property
    def n_joints(self) -> int:
        """Joints it moves."""
        return int(self.amplitudes.shape[2])

    def sample(self, times: np.ndarray) -> np.ndarray:
        """Reference angles at ``times``.

        Parameters
        ----------
        times : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, K, n)
            ``q_h`` in radians.
        """
        t = np.asarray(times, dtype=float)
        components, columns, n = self.amplitudes.shape[1], self.columns, self.n_joints
        # per component, the (joint, scenario) pairs that move, times last: the ufuncs run along
        # the long axis, and a mix's padding and still operators (zero amplitude) cost nothing
        out = np.zeros((n * columns, t.size))
        for c in range(components):
            amplitude, frequency, phase, decay = (a[:, c].T.reshape(-1) for a in (
                self.amplitudes, self.frequencies, self.phases, self.decays))
            moving = np.flatnonzero(amplitude)
            wave = amplitude[moving, None] * np.sin(frequency[moving, None] * t
                                                     + phase[moving, None])
            decaying = np.flatnonzero(decay[moving])
            wave[decaying] *= np.exp(-decay[moving][decaying, None] * t)
            out[moving] += wave
        return out.reshape(n, columns, t.size).transpose(2, 1, 0)


@dataclass(frozen=True, eq=False)
class RecordedMotion:
    """A recorded operator motion, linearly interpolated.

    Sampled past its last sample it holds the last pose, but runs refuse a motion that ends
    before they do (:func:`check_motion_ends`), as they refuse a delay trace that does.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Strictly increasing sample times in seconds, the first at most 0.
    angles : ndarray, shape (T, n)
        Joint angles in radians at those times.
    """

    times: np.ndarray
    angles: np.ndarray

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        angles = np.asarray(self.angles, dtype=float)
        if angles.ndim != 2 or times.shape != angles.shape[:1] or times.size < 2:
            raise ValueError("a recorded motion needs at least two samples of times (T,) and "
                             f"angles (T, n), got {times.shape} and {angles.shape}")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(angles))):
            raise ValueError("a recorded motion must be finite")
        if np.any(np.diff(times) <= 0):
            raise ValueError("a recorded motion's times must increase strictly")
        if times[0] > 0:
            raise ValueError(f"a recorded motion must start at t = 0, its first sample is at "
                             f"{times[0]:g} s")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "angles", angles)

    @classmethod
    def from_csv(cls, path: str | Path) -> RecordedMotion:
        """Read a CSV with a column ``t`` (seconds) and columns ``q1..qn`` (radians).

        Parameters
        ----------
        path : str or Path
            The file.

        Returns
        -------
        RecordedMotion
            The motion.

        Raises
        ------
        ValueError
            One line naming the file and what is missing or malformed.
        """
        import pandas as pd

        try:
            table = pd.read_csv(path)
        except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as error:
            raise ValueError(f"cannot read the motion file {path}: "
                             f"{str(error).splitlines()[0]}") from None
        joints = [f"q{i}" for i in range(1, len(table.columns))]
        if "t" not in table.columns or not joints or any(c not in table.columns for c in joints):
            raise ValueError(f"the motion file {path} needs columns t, q1..qn (radians), it has "
                             f"{', '.join(map(str, table.columns))}")
        try:
            values = table[["t", *joints]].to_numpy(dtype=float)
        except ValueError:
            raise ValueError(f"the motion file {path} has values that are not numbers") from None
        try:
            return cls(values[:, 0], values[:, 1:])
        except ValueError as error:
            raise ValueError(f"the motion file {path}: {error}") from None

    @property
    def columns(self) -> int:
        """Scenarios it describes: one, shared."""
        return 1

    @property
    def n_joints(self) -> int:
        """Joints it moves."""
        return int(self.angles.shape[1])

    @property
    def duration(self) -> float:
        """Time of the last sample in seconds."""
        return float(self.times[-1])

    def sample(self, times: np.ndarray) -> np.ndarray:
        """Reference angles at ``times``, shape ``(S, 1, n)``.

        Parameters
        ----------
        times : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, 1, n)
            ``q_h`` in radians.
        """
        t = np.asarray(times, dtype=float)
        columns = [np.interp(t, self.times, self.angles[:, i]) for i in range(self.n_joints)]
        return np.stack(columns, axis=-1)[:, None, :]


def check_motion_ends(motion: Motion, duration: float) -> None:
    """Refuse a recorded motion that ends before the run does: it would hold its last pose.

    Parameters
    ----------
    motion : Motion
        The operator motion (only a :class:`RecordedMotion` is checked: the others never end).
    duration : float
        Length of the run in seconds (a nanosecond short of it is the run's end: a length
        counted in control periods may be rounded up).

    Raises
    ------
    ValueError
        One line with the motion's end and the run's length.
    """
    if isinstance(motion, RecordedMotion) and motion.duration < duration - 1e-9:
        raise ValueError(f"the recorded operator motion ends at {motion.duration:g} s, before the "
                         f"{duration:g} s run does: record a longer motion or shorten the run")


def smooth_motions(rng: np.random.Generator, batch: int, n_joints: int,
                   amplitude: tuple[float, float], frequency: tuple[float, float],
                   decay: tuple[float, float] = (0.0, 0.0), components: int = 3) -> SineMotion:
    """Draw random smooth motions: ``components`` sines per joint and scenario.

    Each joint's amplitude ``A`` is drawn from ``U(amplitude)`` and shared by its components in
    proportions drawn from a flat Dirichlet law (so ``|q_h,i| <= A``), frequencies (Hz) from
    ``U(frequency)``, phases from ``U[0, 2 pi)`` and decay rates (1/s) from ``U(decay)``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    batch : int
        Scenarios.
    n_joints : int
        Joints.
    amplitude : (float, float)
        Range of each joint's peak angle in radians.
    frequency : (float, float)
        Range of the components' frequencies in Hz.
    decay : (float, float)
        Range of the decay rates in 1/s (zero: motions that never die out).
    components : int
        Sines per joint.

    Returns
    -------
    SineMotion
        ``batch`` columns.
    """
    shape = (batch, components, n_joints)
    share = rng.dirichlet(np.ones(components), size=(batch, n_joints)).transpose(0, 2, 1)
    peak = rng.uniform(*amplitude, size=(batch, 1, n_joints))
    hertz = rng.uniform(*frequency, size=shape)
    return SineMotion(peak * share, 2 * math.pi * hertz, rng.uniform(0, 2 * math.pi, size=shape),
                      rng.uniform(*decay, size=shape))
