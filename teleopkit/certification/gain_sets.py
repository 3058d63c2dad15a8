"""Gain boxes and gain polytopes in the remote action space ``a = [K_r^1..K_r^n, B_r^1..B_r^n]``.

A :class:`GainBox` is what a user asks about (``--kr MIN:MAX --br MIN:MAX``); a
:class:`GainPolytope` ``{a : G a <= h}`` is what a certificate hands to the safety layer. Both
serialise to plain dictionaries for JSON.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["GainBox", "GainPolytope", "box_within", "parse_range"]


def parse_range(text: str, name: str) -> tuple[float, float]:
    """Parse ``MIN:MAX`` (or a single value ``V`` for ``V:V``) into a checked range.

    Parameters
    ----------
    text : str
        The range.
    name : str
        Name used in error messages (for example ``--kr``).

    Returns
    -------
    tuple of float
        ``(low, high)`` with ``0 <= low <= high < inf``.
    """
    parts = text.split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"{name} must be MIN:MAX with numbers, got {text!r}") from None
    if len(values) == 1:
        values *= 2
    if len(values) != 2:
        raise ValueError(f"{name} must be MIN:MAX, got {text!r}")
    low, high = values
    _check_range(name, low, high)
    return low, high


def box_within(inner: tuple[np.ndarray, np.ndarray], outer: tuple[np.ndarray, np.ndarray]
               ) -> bool:
    """Whether the box ``inner`` lies in ``outer``, to the rounding of computed vertices.

    Parameters
    ----------
    inner, outer : tuple of ndarray
        Boxes ``(lower, upper)`` of gain vectors, of one shape.

    Returns
    -------
    bool
        ``True`` if every bound of ``inner`` is within ``outer`` (up to 1e-9 relative).
    """
    slack = 1e-9 * np.maximum(1.0, np.abs(outer[1]))
    return bool(np.all(inner[0] >= outer[0] - slack) and np.all(inner[1] <= outer[1] + slack))


def _pair(name: str, value: Any) -> tuple[float, float]:
    """``value`` as a ``(min, max)`` pair of numbers, or a one-line error naming ``name``."""
    message = f"{name} range must be a (min, max) pair, got {value!r}"
    if isinstance(value, str):  # "5:10" as --kr takes it, or one number
        raise TypeError(f"{message} (parse_range reads MIN:MAX text)")
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(message) from None
    if len(items) != 2:
        raise ValueError(message)
    try:
        return float(items[0]), float(items[1])
    except (TypeError, ValueError):
        raise TypeError(f"{message}: not numbers") from None


def _ranges(name: str, ranges: object) -> tuple[tuple[float, float], ...]:
    """One checked ``(min, max)`` pair of ``name`` per joint (:func:`_pair`)."""
    if isinstance(ranges, str) or not isinstance(ranges, Iterable):
        raise TypeError(f"{name} ranges must be one (min, max) pair per joint, got "
                        f"{type(ranges).__name__}")
    return tuple(_pair(name, pair) for pair in ranges)


def _check_range(name: str, low: float, high: float) -> None:
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"{name} range must be finite, got {low}:{high}")
    if low < 0:
        raise ValueError(f"{name} range must be non-negative, got {low}:{high}")
    if low > high:
        raise ValueError(f"{name} range is inverted ({low} > {high})")


@dataclass(frozen=True)
class GainBox:
    """Per-joint ranges of the remote gains.

    Parameters
    ----------
    kr : tuple of (float, float)
        ``(min, max)`` of ``K_r`` for each joint.
    br : tuple of (float, float)
        ``(min, max)`` of ``B_r`` for each joint.
    """

    kr: tuple[tuple[float, float], ...]
    br: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        kr, br = _ranges("K_r", self.kr), _ranges("B_r", self.br)
        if not kr or len(kr) != len(br):
            raise ValueError("gain box needs one K_r and one B_r range per joint")
        for name, ranges in (("K_r", kr), ("B_r", br)):
            for low, high in ranges:
                _check_range(name, low, high)
        object.__setattr__(self, "kr", kr)
        object.__setattr__(self, "br", br)

    @classmethod
    def uniform(cls, kr: tuple[float, float], br: tuple[float, float],
                n_joints: int = 2) -> GainBox:
        """The same ``K_r`` and ``B_r`` ranges on every joint.

        Parameters
        ----------
        kr : tuple of (float, float)
            ``(min, max)`` of ``K_r``.
        br : tuple of (float, float)
            ``(min, max)`` of ``B_r``.
        n_joints : int
            Number of joints.

        Returns
        -------
        GainBox
            The box with ``n_joints`` copies of each range.
        """
        return cls((kr,) * n_joints, (br,) * n_joints)

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.kr)

    @property
    def lower(self) -> np.ndarray:
        """Lower corner as an action vector."""
        return np.array([lo for lo, _ in self.kr + self.br])

    @property
    def upper(self) -> np.ndarray:
        """Upper corner as an action vector."""
        return np.array([hi for _, hi in self.kr + self.br])

    def joint(self, i: int) -> GainBox:
        """The one-joint box of joint ``i``.

        Parameters
        ----------
        i : int
            Joint index, from 0.

        Returns
        -------
        GainBox
            A box with the ``K_r`` and ``B_r`` ranges of joint ``i`` only.
        """
        return GainBox((self.kr[i],), (self.br[i],))

    def to_dict(self) -> dict[str, list[list[float]]]:
        """Plain-data form for JSON."""
        return {"kr": [list(r) for r in self.kr], "br": [list(r) for r in self.br]}


@dataclass(frozen=True)
class GainPolytope:
    """Admissible gains ``{a : G a <= h}``, a product of one convex polygon per joint.

    Parameters
    ----------
    G : ndarray, shape (m, 2 n)
        Constraint normals.
    h : ndarray, shape (m,)
        Constraint offsets.
    labels : tuple of str
        What each row expresses (for reports of active constraints).
    """

    G: np.ndarray
    h: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        g = np.atleast_2d(np.asarray(self.G, dtype=float))
        h = np.asarray(self.h, dtype=float).reshape(-1)
        if g.shape[0] != h.size or len(self.labels) != h.size:
            raise ValueError(f"polytope has {g.shape[0]} normals, {h.size} offsets and "
                             f"{len(self.labels)} labels")
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
            raise ValueError("polytope data must be finite")
        object.__setattr__(self, "G", g)
        object.__setattr__(self, "h", h)
        object.__setattr__(self, "labels", tuple(self.labels))

    @classmethod
    def from_box(cls, box: GainBox) -> GainPolytope:
        """The box itself as a polytope.

        Parameters
        ----------
        box : GainBox
            Per-joint gain ranges.

        Returns
        -------
        GainPolytope
            ``4 n`` rows: ``a <= upper`` then ``-a <= -lower``, labelled ``"K_r1 <= max"``,
            ``"K_r1 >= min"`` and so on.
        """
        n = box.n_joints
        eye = np.eye(2 * n)
        names = [f"K_r{i + 1}" for i in range(n)] + [f"B_r{i + 1}" for i in range(n)]
        return cls(np.vstack([eye, -eye]), np.concatenate([box.upper, -box.lower]),
                   tuple([f"{v} <= max" for v in names] + [f"{v} >= min" for v in names]))

    def intersect(self, normals: np.ndarray, offsets: np.ndarray,
                  labels: tuple[str, ...]) -> GainPolytope:
        """Add the rows ``normals a <= offsets``.

        Parameters
        ----------
        normals : ndarray, shape (k, 2 n)
            Normals of the new constraints.
        offsets : ndarray, shape (k,)
            Offsets of the new constraints.
        labels : tuple of str
            What each new row expresses.

        Returns
        -------
        GainPolytope
            A new polytope with the rows of this one followed by the new rows.
        """
        return GainPolytope(np.vstack([self.G, normals]), np.concatenate([self.h, offsets]),
                            self.labels + labels)

    @property
    def dimension(self) -> int:
        """Dimension ``2 n`` of the action space."""
        return self.G.shape[1]

    def contains(self, actions: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Whether each action satisfies every constraint within ``tol``.

        Parameters
        ----------
        actions : ndarray, shape (..., 2 n)
            Gain vectors ``[K_r^1..K_r^n, B_r^1..B_r^n]``.
        tol : float
            Absolute tolerance added to every offset: ``G a <= h + tol``.

        Returns
        -------
        ndarray of bool, shape (...)
            Whether each action lies in the polytope.
        """
        actions = np.asarray(actions, dtype=float)
        return (actions @ self.G.T <= self.h + tol).all(axis=-1)

    def joint_vertices(self, i: int) -> np.ndarray:
        """Vertices ``(K_r^i, B_r^i)`` of joint ``i``'s polygon.

        Only rows that involve joint ``i`` alone are used (the polytope is a product of joints).

        Parameters
        ----------
        i : int
            Joint index, from 0.

        Returns
        -------
        ndarray, shape (k, 2)
            The vertices in counter-clockwise order around their centroid; ``k = 0`` when the
            polygon is empty.
        """
        n = self.dimension // 2
        cols = [i, n + i]
        others = np.delete(np.arange(2 * n), cols)
        rows = np.all(self.G[:, others] == 0, axis=1) & np.any(self.G[:, cols] != 0, axis=1)
        g, h = self.G[rows][:, cols], self.h[rows]
        points = []
        for a, b in itertools.combinations(range(len(h)), 2):
            pair = g[[a, b]]
            if abs(np.linalg.det(pair)) < 1e-12:
                continue
            point = np.linalg.solve(pair, h[[a, b]])
            if np.all(g @ point <= h + 1e-9 * (1 + np.abs(h))):
                points.append(point)
        if not points:
            return np.empty((0, 2))
        points_array = np.unique(np.round(np.array(points), 12), axis=0)
        centre = points_array.mean(axis=0)
        order = np.argsort(np.arctan2(*(points_array - centre).T[::-1]))
        return points_array[order]

    def vertices(self) -> np.ndarray:
        """All vertices of the product polytope, shape ``(k, 2 n)``."""
        n = self.dimension // 2
        per_joint = [self.joint_vertices(i) for i in range(n)]
        out = []
        for combo in itertools.product(*per_joint):
            pairs = np.array(combo)
            out.append(np.concatenate([pairs[:, 0], pairs[:, 1]]))
        return np.array(out).reshape(-1, 2 * n)

    def is_empty(self) -> bool:
        """Whether some joint has no admissible gain."""
        return any(self.joint_vertices(i).size == 0 for i in range(self.dimension // 2))

    def same_as(self, other: GainPolytope) -> bool:
        """Whether ``other`` has the same rows ``G x <= h`` (to rounding).

        Parameters
        ----------
        other : GainPolytope
            Another polytope.

        Returns
        -------
        bool
            ``True`` for the same inequalities in the same order.
        """
        return (self.G.shape == other.G.shape
                and bool(np.allclose(self.G, other.G, rtol=1e-12, atol=0))
                and bool(np.allclose(self.h, other.h, rtol=1e-12, atol=1e-15)))

    def to_dict(self) -> dict[str, object]:
        """Plain-data form for JSON (``G``, ``h``, ``labels``)."""
        return {"G": self.G.tolist(), "h": self.h.tolist(), "labels": list(self.labels)}

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> GainPolytope:
        """Inverse of :meth:`to_dict`; raises ValueError on malformed data.

        Parameters
        ----------
        data : dict
            Plain data with the keys ``G``, ``h`` and ``labels``, as :meth:`to_dict` returns.

        Returns
        -------
        GainPolytope
            The polytope.
        """
        try:
            return cls(np.array(data["G"], dtype=float), np.array(data["h"], dtype=float),
                       tuple(str(s) for s in data["labels"]))  # type: ignore[attr-defined]
        except (KeyError, TypeError) as error:
            raise ValueError(f"malformed gain polytope: {error}") from None
