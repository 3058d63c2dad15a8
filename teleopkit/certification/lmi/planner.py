"""What a cover solves next, and what it has found: the search policy, without any solving.

:class:`CoverPlan` is the state of one cover
(:func:`~teleopkit.certification.lmi.cover.cover_certificate`): the certified cells, the boxes
of the split still to solve, the gain vertices to check alone. Its
methods say what the next level is and take the verdicts back; the cover solves in the worker
pool what the plan asks for (the executor). The cells and the split are boxes of the gain space
(``(lower, upper)`` arrays); :func:`clip` is the set inside one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from certify import Certificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.cells import Box, CellMemo

__all__ = ["CORNERS_AT_ONCE", "MIN_RATIO", "Cover", "CoverPlan", "Level", "clip", "halves",
           "splittable"]

CORNERS_AT_ONCE = 2
"""Gain vertices a cover checks alone side by side before it looks at their verdicts (fixed, so
a cover spends the same solves on every machine)."""

MIN_RATIO = 1.001
"""A failing cell whose every gain range is narrower than this ratio is not split further."""


@dataclass(frozen=True)
class Cover:
    """Outcome of :func:`~teleopkit.certification.lmi.cover.cover_certificate`.

    Parameters
    ----------
    certified : bool
        Whether every constant gain of the set is certified.
    cells : tuple of GainPolytope
        The certified cells (their union is the set when ``certified``).
    certificates : tuple of certify.Certificate
        One per certified cell, then, if not certified, the certificate that failed last.
    solves : int
        Number of LMI solves, failed ones included.
    reason : str
        Why the cover is incomplete (empty when certified).
    boxes : tuple
        The box ``(lower, upper)`` each cell is the set clipped to (``None``: the cell is the
        whole set), one per cell.
    empty : tuple
        Boxes of the split that miss the set (no certificate needed): with ``boxes`` they tile
        the set's bounding box, which is what makes the cells a cover.
    variation : str
        The gain class each cell's certificate covers (``"switching"`` for split cells).
    root : tuple or None
        The box ``(lower, upper)`` that was split (it contains the set; ``None``: the set's
        bounding box).
    """

    certified: bool
    cells: tuple[GainPolytope, ...]
    certificates: tuple[Certificate, ...]
    solves: int
    reason: str = ""
    boxes: tuple[Box | None, ...] = ()
    empty: tuple[Box, ...] = ()
    variation: str = "switching"
    root: Box | None = None


def clip(polytope: GainPolytope, box: Box) -> GainPolytope:
    """The part of a gain set inside a box.

    Parameters
    ----------
    polytope : GainPolytope
        The set.
    box : (ndarray, ndarray)
        ``(lower, upper)`` corners in action space ``[K_r..., B_r...]``.

    Returns
    -------
    GainPolytope
        Their intersection (possibly empty).
    """
    lower, upper = box
    n = lower.size // 2
    cut = GainPolytope.from_box(GainBox(tuple(zip(lower[:n], upper[:n], strict=True)),
                                        tuple(zip(lower[n:], upper[n:], strict=True))))
    return polytope.intersect(cut.G, cut.h, cut.labels)


def _ratios(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``max / min`` of each gain range (``inf`` for a range that starts at zero)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(upper > lower, upper / lower, 1.0)


def splittable(box: Box) -> bool:
    """Whether some gain range of the box is at least :data:`MIN_RATIO` wide in ratio.

    Parameters
    ----------
    box : (ndarray, ndarray)
        ``(lower, upper)``.

    Returns
    -------
    bool
        ``True`` if :func:`halves` may split it.
    """
    return bool(_ratios(*box).max() >= MIN_RATIO)


def halves(box: Box) -> list[Box]:
    """Split the widest range (in ratio) at its geometric mean (midpoint from zero).

    Parameters
    ----------
    box : (ndarray, ndarray)
        ``(lower, upper)``.

    Returns
    -------
    list of (ndarray, ndarray)
        The two halves.
    """
    lower, upper = box
    axis = int(np.argmax(_ratios(lower, upper)))
    low, high = lower[axis], upper[axis]
    cut = np.sqrt(low * high) if low > 0 else 0.5 * (low + high)
    first_upper, second_lower = upper.copy(), lower.copy()
    first_upper[axis] = second_lower[axis] = cut
    return [(lower, first_upper), (second_lower, upper)]


def _split_again(wave: list[Box]) -> list[Box]:
    """The next level's halves, halved once more where they are wide enough to split.

    Used after a level in which no cell was certified: its halves are nearly as wide and would
    mostly fail too, so the level is skipped (two halvings, the boxes of the level after it).
    """
    return [half for box in wave for half in (halves(box) if splittable(box) else [box])]


@dataclass(frozen=True)
class Level:
    """One level of the split: its cells, the verdicts already known, those to solve.

    Attributes
    ----------
    todo : list of (Box, GainPolytope)
        The level's boxes that meet the set, with the set inside each.
    known : list of certify.Certificate or None
        The memo's verdict on each (None: unknown).
    fresh : list of int
        Indices of ``todo`` to solve.
    """

    todo: list[tuple[Box, GainPolytope]]
    known: list[Certificate | None]
    fresh: list[int]


@dataclass
class CoverPlan:
    """The state of a cover and its search policy (no solving: the cover does that).

    Parameters
    ----------
    polytope : GainPolytope
        The set to cover.
    ordered : ndarray, shape (V, 2 n)
        Its corners, the one the closed form finds weakest first.
    root : (ndarray, ndarray), optional
        The box to split (default the set's bounding box).

    Attributes
    ----------
    solves : int
        LMI solves spent (the cover adds them).
    cells, certificates, boxes : list
        The certified cells, their certificates and boxes.
    empty : list
        Boxes of the split that miss the set.
    wave : list
        The boxes of the next level.
    checks : list of ndarray
        Gain vertices to check alone before the next level.
    """

    polytope: GainPolytope
    ordered: np.ndarray
    root: Box | None = None
    solves: int = field(default=0, init=False)
    cells: list[GainPolytope] = field(default_factory=list, init=False)
    certificates: list[Certificate] = field(default_factory=list, init=False)
    boxes: list[Box | None] = field(default_factory=list, init=False)
    empty: list[Box] = field(default_factory=list, init=False)
    wave: list[Box] = field(default_factory=list, init=False)
    checks: list[np.ndarray] = field(default_factory=list, init=False)
    failures: int = field(default=0, init=False)
    vertices_checked: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        bounding = (self.ordered.min(axis=0), self.ordered.max(axis=0))
        self.wave = [bounding if self.root is None else self.root]

    def level(self, memo: CellMemo) -> Level:
        """The boxes of the next level that meet the set (the others are recorded as empty).

        Parameters
        ----------
        memo : CellMemo
            Verdicts known so far.

        Returns
        -------
        Level
            The cells, their known verdicts and the ones to solve.
        """
        todo = []
        for box in self.wave:
            cell = clip(self.polytope, box)
            if cell.is_empty():
                self.empty.append(box)
            else:
                todo.append((box, cell))
        known = [memo.recall(box, cell) for box, cell in todo]
        return Level(todo, known, [k for k, cert in enumerate(known) if cert is None])

    def corner_checks(self, memo: CellMemo) -> list[np.ndarray]:
        """Gain vertices to check alone before the level (those the memo does not know).

        Parameters
        ----------
        memo : CellMemo
            Verdicts known so far.

        Returns
        -------
        list of ndarray
            The actions.
        """
        return [action for action in self.checks if memo.vertex(action) is None]

    def beside(self, memo: CellMemo, level: Level) -> list[np.ndarray]:
        """The weakest corner, checked beside the first solve when that is the whole set.

        Parameters
        ----------
        memo : CellMemo
            Verdicts known so far.
        level : Level
            The level about to be solved.

        Returns
        -------
        list of ndarray
            The weakest corner, or nothing.
        """
        weakest = self.ordered[0]
        first = self.solves == 0 and len(level.fresh) == 1 and memo.vertex(weakest) is None
        return [weakest] if first else []

    def unfinished(self, reason: str, failed: tuple[Certificate, ...] = ()) -> Cover:
        """The cover as it stands, not certified, with why.

        Parameters
        ----------
        reason : str
            Why the search ended.
        failed : tuple of certify.Certificate
            The certificate that failed last, if any.

        Returns
        -------
        Cover
            Not certified.
        """
        return Cover(False, tuple(self.cells), (*self.certificates, *failed), self.solves,
                     reason, tuple(self.boxes), tuple(self.empty), root=self.root)

    def finished(self) -> Cover:
        """The certified cover.

        Returns
        -------
        Cover
            Certified: its cells tile the set.
        """
        return Cover(True, tuple(self.cells), tuple(self.certificates), self.solves, "",
                     tuple(self.boxes), tuple(self.empty), root=self.root)

    def absorb(self, level: Level, memo: CellMemo) -> Cover | None:
        """Take a solved level's verdicts: keep its certified cells, split the others.

        Parameters
        ----------
        level : Level
            The level with its verdicts (None: not solved, because its level's most promising
            cells failed; such a cell is split without a look at its size).
        memo : CellMemo
            The verdicts known so far (for the next corner checks).

        Returns
        -------
        Cover or None
            The unfinished cover if a failing cell cannot be split, else None (search on).
        """
        wave, certified_before = [], len(self.cells)
        for (box, cell), cert in zip(level.todo, level.known, strict=True):
            if cert is not None and cert.certified:
                self.cells.append(cell)
                self.certificates.append(cert)
                self.boxes.append(box)
                continue
            if cert is not None and not splittable(box):
                return self.unfinished(f"the cell around {box[0].tolist()} is too small to "
                                       "split further", (cert,))
            self.failures += 1
            wave.extend(halves(box))
        level_failed = len(self.cells) == certified_before
        self.wave = _split_again(wave) if level_failed else wave
        self._plan_checks(level_failed, memo)
        return None

    def _plan_checks(self, level_failed: bool, memo: CellMemo) -> None:
        """The gain vertices to check alone before the next level.

        After the first failure, the next :data:`CORNERS_AT_ONCE` weakest corners not yet
        checked; once a whole level fails or the split has failed as many cells as the set has
        corners, all of them (once).
        """
        self.checks = []
        if self.failures == 1 and self.wave:
            self.checks = [action for action in self.ordered
                           if memo.vertex(action) is None][:CORNERS_AT_ONCE]
        elif self.wave and not self.vertices_checked and (
                level_failed or self.failures >= len(self.ordered)):
            self.vertices_checked = True
            self.checks = list(self.ordered)
