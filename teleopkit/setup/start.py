"""Where the arms start: fixed positions, or ranges each scenario draws from.

The ``start`` key of a setup file is ``paper`` (``q_l = [-0.2, 0.2]``, ``q_r = [-0.1, 0.1]``,
``theta_r = 0``), ``rest`` (everything at the origin), ``aligned`` (all three at the paper's
local start: no tracking error, no spring deflection), or a mapping of ``local``, ``remote``
and ``motor`` (positions in radians, zero where left out), each a list or a range
``{min: [...], max: [...]}`` drawn uniformly per scenario; or a list of these, each scenario
drawing one of them (:class:`StartMix`). Velocities start at zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from teleopkit.model.params import InitialState
from teleopkit.setup.reading import Node

__all__ = ["StartMix", "StartSpec"]

_PARTS = ("local", "remote", "motor")
_PAPER = InitialState()


@dataclass(frozen=True)
class StartSpec:
    """Initial positions of each scenario: fixed, or drawn from ranges.

    Parameters
    ----------
    low, high : ndarray, shape (3, n)
        Bounds of ``q_l(0)``, ``q_r(0)`` and ``theta_r(0)`` (equal where fixed).
    """

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        low = np.array(self.low, dtype=float)
        high = np.array(self.high, dtype=float)
        if low.shape != high.shape or low.ndim != 2 or low.shape[0] != 3:
            raise ValueError(f"start bounds need shape (3, n), got {low.shape}, {high.shape}")
        if np.any(low > high) or not np.all(np.isfinite(low) & np.isfinite(high)):
            raise ValueError("start bounds must be finite with low <= high")
        low.flags.writeable = high.flags.writeable = False
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, StartSpec) and np.array_equal(self.low, other.low)
                and np.array_equal(self.high, other.high))

    def __hash__(self) -> int:
        return hash((self.low.tobytes(), self.high.tobytes()))

    @classmethod
    def fixed(cls, initial: InitialState) -> StartSpec:
        """One start for every scenario.

        Parameters
        ----------
        initial : InitialState
            The positions.

        Returns
        -------
        StartSpec
            A fixed start.
        """
        positions = np.array([initial.local, initial.remote, initial.motor])
        return cls(positions, positions)

    @classmethod
    def named(cls, name: str, n: int) -> StartSpec | None:
        """A named start.

        Parameters
        ----------
        name : str
            ``paper``, ``rest`` or ``aligned`` (the first and last for two joints only).
        n : int
            Joints.

        Returns
        -------
        StartSpec or None
            The start, or None for another name.
        """
        if name == "rest":
            return cls(np.zeros((3, n)), np.zeros((3, n)))
        if n != 2 or name not in ("paper", "aligned"):
            return None
        if name == "paper":
            return cls.fixed(_PAPER)
        return cls.fixed(InitialState(_PAPER.local, _PAPER.local, _PAPER.local))

    @classmethod
    def from_node(cls, node: Node, n: int) -> StartSpec:
        """Read a ``start`` entry.

        Parameters
        ----------
        node : Node
            The entry.
        n : int
            Joints.

        Returns
        -------
        StartSpec
            The start.
        """
        if isinstance(node.value, str):
            spec = cls.named(node.text(), n)
            if spec is None:
                names = "rest" if n != 2 else "paper, rest, aligned"
                raise node.error(f"unknown start {node.value!r} for {n} joints; use {names} or "
                                 "a mapping of local, remote, motor")
            return spec
        entries = node.fields(_PARTS)
        low, high = np.zeros((3, n)), np.zeros((3, n))
        for row, part in enumerate(_PARTS):
            if part not in entries:
                continue
            entry = entries[part]
            if isinstance(entry.value, dict):
                bounds = entry.fields(("min", "max"), ("min", "max"))
                low[row], high[row] = bounds["min"].numbers(n), bounds["max"].numbers(n)
                if np.any(low[row] > high[row]):
                    raise entry.error("min above max")
            else:
                low[row] = high[row] = entry.numbers(n)
        return cls(low, high)

    @property
    def n_joints(self) -> int:
        """Joints."""
        return int(self.low.shape[1])

    @property
    def is_fixed(self) -> bool:
        """Whether every scenario starts at the same positions."""
        return bool(np.array_equal(self.low, self.high))

    @property
    def boxes(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The start's box of positions, ``((low, high),)``, each ``(3, n)``."""
        return ((self.low, self.high),)

    def initial(self) -> InitialState:
        """The start of the model: the fixed positions, or the middle of the ranges."""
        middle = (self.low + self.high) / 2
        return InitialState(*(tuple(row) for row in middle))

    def draw(self, rng: np.random.Generator, batch: int) -> np.ndarray:
        """Starts of the scenarios.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws (untouched when the start is fixed).
        batch : int
            Scenarios.

        Returns
        -------
        ndarray
            ``(1, 3, n)`` if fixed, else ``(batch, 3, n)``.
        """
        if self.is_fixed:
            return self.low[None].copy()
        return rng.uniform(self.low, self.high, size=(batch, *self.low.shape))

    def to_data(self) -> Any:
        """The start as setup-file data (a name where it has one)."""
        n = self.low.shape[1]
        for name in ("paper", "rest", "aligned"):
            if self == StartSpec.named(name, n):
                return name
        return {part: ([float(v) for v in self.low[row]] if np.array_equal(
            self.low[row], self.high[row]) else {"min": [float(v) for v in self.low[row]],
                                                 "max": [float(v) for v in self.high[row]]})
                for row, part in enumerate(_PARTS)}

    def describe(self) -> str:
        """One line for people."""
        data = self.to_data()
        if isinstance(data, str):
            return {"paper": "the paper's start", "rest": "at rest at the origin",
                    "aligned": "aligned (no tracking error, no spring deflection)"}[data]
        return "fixed positions" if self.is_fixed else "random starts drawn per scenario"


@dataclass(frozen=True)
class StartMix:
    """Several starts, each scenario drawing one of them uniformly.

    Parameters
    ----------
    parts : tuple of StartSpec
        The starts (at least two, same number of joints).
    """

    parts: tuple[StartSpec, ...]

    def __post_init__(self) -> None:
        if len(self.parts) < 2 or len({part.n_joints for part in self.parts}) != 1:
            raise ValueError("a mix of starts needs two or more starts of the same joints")

    @classmethod
    def from_node(cls, node: Node, n: int) -> StartSpec | StartMix:
        """Read a ``start`` entry: one start, or a list of them.

        Parameters
        ----------
        node : Node
            The entry.
        n : int
            Joints.

        Returns
        -------
        StartSpec or StartMix
            The start(s).
        """
        if not isinstance(node.value, list):
            return StartSpec.from_node(node, n)
        parts = tuple(StartSpec.from_node(item, n) for item in node.items())
        return parts[0] if len(parts) == 1 else cls(parts)

    @property
    def n_joints(self) -> int:
        """Joints."""
        return self.parts[0].n_joints

    @property
    def is_fixed(self) -> bool:
        """Whether every scenario starts at the same positions (never, for a mix)."""
        return False

    @property
    def boxes(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """Every part's box of positions, ``(low, high)`` pairs of shape ``(3, n)``."""
        return tuple(box for part in self.parts for box in part.boxes)

    def initial(self) -> InitialState:
        """The start of the model: the first part's."""
        return self.parts[0].initial()

    def draw(self, rng: np.random.Generator, batch: int) -> np.ndarray:
        """Starts of the scenarios, ``(batch, 3, n)``.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws: the part of each scenario, then its positions.
        batch : int
            Scenarios.

        Returns
        -------
        ndarray, shape (batch, 3, n)
            ``q_l(0), q_r(0), theta_r(0)`` of each scenario.
        """
        choice = rng.integers(len(self.parts), size=batch)
        low = np.stack([self.parts[k].low for k in choice])
        high = np.stack([self.parts[k].high for k in choice])
        return rng.uniform(low, high)

    def to_data(self) -> list[Any]:
        """The starts as setup-file data (a list)."""
        return [part.to_data() for part in self.parts]

    def describe(self) -> str:
        """One line for people."""
        return "one of: " + "; ".join(part.describe() for part in self.parts)
