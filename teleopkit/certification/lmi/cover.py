"""Constant gains of a large set, certified by covering the set with cells.

For frozen (constant) gains the least conservative LMI lets the functional depend on the gains,
which needs every gain vertex as a system: ``4^n`` of them, too many for two joints (see
:mod:`teleopkit.certification.lmi.systems`). A set of constant gains is certified just as well by
cells that cover it, each certified on its own. Here each cell is certified for gains *switching*
inside it (one functional, gains as a multiplier uncertainty: a few seconds per cell), which is
conservative on a wide cell but close to the frozen certificate on a narrow one. Cells that fail are
halved along the gain whose range is widest in ratio (``max / min``), at the geometric mean, until
every cell is certified, a cell cannot be split further, or the budget of solves is spent. After a
level in which no cell is certified, the failed cells are split twice (the level between is skipped:
its cells are nearly as wide and mostly fail too). A level of more than :data:`PROBES` cells first
solves its most promising ones (largest closed-form margin at the weakest vertex); if one of them
fails, the whole level is split without solving the rest, which would mostly fail too. The cells of
one level of the split are solved together on the local cores
(:mod:`~teleopkit.certification.lmi.workers`), and a cell's LMI is retried in balanced coordinates
only after an accurate solve (:data:`CELL_RETRY`): a failed cell is split anyway.  No LMI certifies
a cell whose corner it cannot certify alone, and a corner alone is a smaller problem than a cell, so
corners are checked before the cells that would need them: the one the closed form finds weakest
side by side with the whole set (the first cell), the next :data:`CORNERS_AT_ONCE` weakest after
the first failure, then all of them once a whole level fails or the split has failed as many
cells as the set has corners, weakest first, :data:`CORNERS_AT_ONCE` at a time. A gain point of
the set found not certified alone, now or by an earlier cover sharing the memo, ends the search
at once.

The delay margin of constant gains follows the same way (:func:`cover_margin`): the frozen LMI
margin of the vertex that limits the closed form bounds it from above, and covers are tried at
bounds descending geometrically from there until one certifies the whole set.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from certify import Certificate
from teleopkit.certification.gain_sets import GainPolytope, box_within
from teleopkit.certification.lmi.cells import CellMemo
from teleopkit.certification.lmi.planner import (
    CORNERS_AT_ONCE,
    MIN_RATIO,
    Cover,
    CoverPlan,
    Level,
    splittable,
)
from teleopkit.certification.lmi.systems import (
    LMI_METHOD,
    NO_LOWER,
    DelayQuestion,
    enumerated,
    vertex_certificate,
)
from teleopkit.certification.lmi.workers import map_solves, workers
from teleopkit.certification.nuno.condition import nuno_joint_margins, weakest_first
from teleopkit.model.params import TeleoperatorParams

__all__ = ["CELL_BUDGET", "CELL_RETRY", "CORNERS_AT_ONCE", "LIMIT_RTOL", "MIN_RATIO", "PROBES",
           "Cover", "CoverMargin", "cover_certificate", "cover_margin", "limiting_vertex",
           "set_certificate", "vertex_margin"]

_log = logging.getLogger(__name__)

CELL_BUDGET = 400
"""Most cell solves :func:`cover_certificate` spends before it gives up (not certified)."""

CELL_RETRY = "accurate"
"""A cell retries in balanced coordinates only after an accurate solve failed: on the paper's
two-joint teleoperator no cell whose first solve ended ``optimal_inaccurate`` was certified by
the retry (0 of 20), while a failed cell is split anyway."""

PROBES = 2
"""Cells of a level solved first, the most promising ones: if one fails, the rest of the level
is split without being solved (fixed, so a cover spends the same solves on every machine)."""

LIMIT_RTOL = 0.05
"""Relative precision of :func:`limiting_vertex`'s margin."""

_SMALLEST = 1e-4
"""A bracket ``[T_min, T_min + this]`` without a certified bound ends a margin search (0 s)."""

def cover_certificate(question: DelayQuestion, polytope: GainPolytope,
                      budget: int = CELL_BUDGET, memo: CellMemo | None = None,
                      root: tuple[np.ndarray, np.ndarray] | None = None) -> Cover:
    """Certify every constant gain of a polytope for a question's delays, by cells.

    Parameters
    ----------
    question : DelayQuestion
        Plant, delay bounds, lower bounds and LMI method.
    polytope : GainPolytope
        Remote gains (a product of one polygon per joint), not empty.
    budget : int
        Most LMI solves to spend (vertex checks included).
    memo : CellMemo, optional
        Verdicts of earlier covers of the same question, used and extended
        (:mod:`~teleopkit.certification.lmi.cells`); by default a new one.
    root : tuple of ndarray, optional
        The box ``(lower, upper)`` to split, containing the polytope; by default its bounding
        box. Covers of nested sets that split the same root meet the same boxes, which is what
        lets them share a memo.

    Returns
    -------
    Cover
        The verdict, the certified cells and their certificates.

    Raises
    ------
    ValueError
        If the polytope is empty or outside ``root``, ``budget`` is not positive or ``memo`` is
        for another question.
    """
    if budget < 1:
        raise ValueError(f"budget must be a positive number of solves, got {budget}")
    corners = polytope.vertices()
    if corners.size == 0:
        raise ValueError("the gain set is empty: nothing to certify")
    memo = memo if memo is not None else CellMemo(question)
    if memo.question != question:
        raise ValueError("the cell memo holds verdicts of another question (plant, delay "
                         "bounds or method)")
    if root is not None and not box_within((corners.min(axis=0), corners.max(axis=0)), root):
        raise ValueError("the gain set reaches outside the root box of its cover")
    # the plan decides what to solve (planner); this loop solves it in the pool (executor)
    plan = CoverPlan(polytope, corners[weakest_first(question.params, corners)], root)
    while plan.wave:
        level = plan.level(memo)
        unchecked, beside = plan.corner_checks(memo), plan.beside(memo, level)
        if plan.solves + len(unchecked) + len(level.fresh) + len(beside) > budget:
            return plan.unfinished(f"budget of {budget} solves spent with {len(level.fresh)} "
                                   "cells left")
        failed = memo.failed_vertex(polytope)  # (one checked beside the last level may fail)
        if failed is None:
            plan.solves += _check_alone(unchecked, memo)
            failed = memo.failed_vertex(polytope)
        if failed is not None:
            return plan.unfinished(f"the gain vertex {failed[0].tolist()} is not certified "
                                   "alone", (failed[1],))
        _log.info("T* = %.4g s: %d cells certified, solving %d (%d known)",
                  max(question.bounds), len(plan.cells), len(level.fresh),
                  len(level.todo) - len(level.fresh))
        solved, count = _solve_level(level, memo, beside)
        plan.solves += count
        known = [solved.get(k, cert) for k, cert in enumerate(level.known)]
        stop = plan.absorb(Level(level.todo, known, level.fresh), memo)
        if stop is not None:
            return stop
    return plan.finished()


def _solve_level(level: Level, memo: CellMemo, beside: Sequence[np.ndarray] = (),
                 ) -> tuple[dict[int, Certificate], int]:
    """Solve a level's fresh cells into the memo; return their verdicts and the solves spent.

    A level of more than :data:`PROBES` cells, all of which could be split, is probed first:
    its :data:`PROBES` most promising cells (largest closed-form margin at their weakest
    vertex) are solved, and the others only if every probe is certified. Otherwise the level
    would mostly fail (the others stay unsolved, to be split without a solve). The gain
    vertices ``beside`` are checked alone side by side with the level's first solves (the
    first cell, the whole set, gets its weakest corner beside it: on a second core the check
    costs no time, and it is the first thing needed when the set fails).
    """
    question, todo, fresh = memo.question, level.todo, level.fresh
    solved: dict[int, Certificate] = {}

    def solve(indices: list[int], corners: Sequence[np.ndarray]) -> list[Certificate]:
        cells = [(question.cell, (todo[k][1], "switching", CELL_RETRY)) for k in indices]
        checks = [(question.vertex, (action,)) for action in corners]
        verdicts = map_solves(_call, cells + checks, share_cores=True)
        for action, verdict in zip(corners, verdicts[len(cells):], strict=True):
            memo.record_vertex(action, verdict)
        for k, cert in zip(indices, verdicts[:len(cells)], strict=True):
            solved[k] = cert
            memo.record(*todo[k], cert)
        return verdicts[:len(cells)]

    extra = len(beside)
    if len(fresh) <= PROBES or not all(splittable(todo[k][0]) for k in fresh):
        return solved, len(solve(fresh, beside)) + extra
    promise = [float(nuno_joint_margins(question.params, todo[k][1].vertices()).min())
               for k in fresh]
    order = [fresh[i] for i in np.argsort(promise, kind="stable")[::-1]]
    probed = solve(order[:PROBES], beside)
    if not all(cert.certified for cert in probed):
        _log.info("the %d most promising of %d cells failed: splitting the level", PROBES,
                  len(fresh))
        return solved, PROBES + extra
    return solved, PROBES + extra + len(solve(order[PROBES:], ()))


def _check_alone(actions: list[np.ndarray], memo: CellMemo) -> int:
    """Solve gain vertices alone into the memo, :data:`CORNERS_AT_ONCE` at a time, in order.

    Stops after the first batch with a vertex not certified (which ends the cover); returns the
    number of solves.
    """
    solves = 0
    for start in range(0, len(actions), CORNERS_AT_ONCE):
        batch = actions[start:start + CORNERS_AT_ONCE]
        solved = map_solves(_call, [(memo.question.vertex, (action,)) for action in batch],
                            share_cores=True)
        solves += len(solved)
        for action, verdict in zip(batch, solved, strict=True):
            memo.record_vertex(action, verdict)
        if not all(verdict.certified for verdict in solved):
            break
    return solves


def _call(solve: Callable[..., Certificate], args: tuple, threads: int = 0) -> Certificate:
    """One solve of a cover on a worker: a cell or a gain vertex alone, on ``threads`` threads."""
    return solve(*args, threads=threads)


def set_certificate(question: DelayQuestion, polytope: GainPolytope,
                    variation: str = "frozen", budget: int = CELL_BUDGET,
                    memo: CellMemo | None = None,
                    root: tuple[np.ndarray, np.ndarray] | None = None) -> Cover:
    """Certify a gain set the cheapest sound way: one LMI, or cells for many constant gains.

    Parameters
    ----------
    question : DelayQuestion
        Plant, delay bounds, lower bounds and LMI method.
    polytope : GainPolytope
        Remote gains, not empty.
    variation : {"frozen", "switching"}
        Gain class. Frozen gains beyond :func:`~teleopkit.certification.lmi.systems.enumerated` are
        covered by cells (:func:`cover_certificate`); everything else is one LMI
        (:func:`~teleopkit.certification.lmi.systems.lmi_certificate`), reported as a one-cell
        cover.
    budget : int
        Most solves for a cover.
    memo : CellMemo, optional
        Verdicts of earlier covers of the same question, for a cover.
    root : tuple of ndarray, optional
        The box a cover splits (:func:`cover_certificate`).

    Returns
    -------
    Cover
        The verdict.
    """
    if variation == "frozen" and not enumerated(question.params, polytope):
        return cover_certificate(question, polytope, budget, memo, root)
    cert = question.cell(polytope, variation)
    if cert.certified:
        return Cover(True, (polytope,), (cert,), 1, boxes=(None,), variation=variation)
    return Cover(False, (), (cert,), 1, f"LMI ({question.method}) {cert.status}, not certified",
                 variation=variation)


@dataclass(frozen=True)
class CoverMargin:
    """Outcome of :func:`cover_margin`.

    Parameters
    ----------
    margin : float
        Largest common delay bound ``T*`` at which a cover certified every constant gain of the
        set (the given lower bound if none did).
    limit : float
        Frozen LMI margin of ``vertex`` alone: no cover certifies beyond it.
    vertex : tuple of float
        The gain vertex with the smallest closed-form margin (where the LMI margin is usually
        smallest too; if another vertex's is smaller, the covers fail on it at once).
    cover : Cover or None
        The cover at ``margin`` (``None`` if no cover was certified).
    solves : int
        LMI solves spent by the covers (the vertex bisections excluded).
    """

    margin: float
    limit: float
    vertex: tuple[float, ...]
    cover: Cover | None
    solves: int


def limiting_vertex(params: TeleoperatorParams, polytope: GainPolytope,
                    method: str = LMI_METHOD, delay_lower: tuple[float, float] = NO_LOWER
                    ) -> tuple[tuple[float, ...], float]:
    """The gain vertex with the smallest closed-form margin and its frozen LMI margin alone.

    Ties go as in :func:`~teleopkit.certification.nuno.condition.weakest_first`.

    The LMI margin of any one gain bounds the margin of every set that contains it, so this is
    an upper limit of the set's constant-gain margin (:func:`vertex_margin`: about 35 s for two
    joints on one core).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains, not empty.
    method : str
        A :data:`certify.METHODS` name.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)`` kept while ``T*`` grows.

    Returns
    -------
    vertex : tuple of float
        The gains ``[K_r..., B_r...]`` of the vertex.
    margin : float
        Its largest certified common delay bound ``T*`` (0 if none).

    Raises
    ------
    ValueError
        If the polytope is empty.
    """
    corners = polytope.vertices()
    if corners.size == 0:
        raise ValueError("the gain set is empty: nothing to certify")
    worst = corners[weakest_first(params, corners)[0]]
    guess = float(nuno_joint_margins(params, worst).min())
    # to 5 %: covers are tried 10 % apart below it, so a closer limit only costs cells
    return tuple(worst.tolist()), vertex_margin(params, worst, method, delay_lower, guess=guess,
                                                rtol=LIMIT_RTOL)


def vertex_margin(params: TeleoperatorParams, action: np.ndarray, method: str = LMI_METHOD,
                  delay_lower: tuple[float, float] = NO_LOWER, guess: float = 1.0,
                  rtol: float = 0.02, h_max: float = 100.0) -> float:
    """Largest common delay bound ``T*`` certified for one constant gain alone, on all cores.

    A section search: each round solves one bound per worker
    (:func:`~teleopkit.certification.lmi.workers.map_solves`), doubling from ``guess`` until a
    bound fails, then at evenly spaced bounds inside the bracket, until the bracket is within
    ``rtol`` (with two workers it narrows three-fold per round, where a bisection halves it per
    solve).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    action : ndarray, shape (2 n,)
        Remote gains ``[K_r..., B_r...]``.
    method : str
        A :data:`certify.METHODS` name.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)``.
    guess : float
        Where to start (the closed-form margin of the gain is a good one).
    rtol : float
        Relative width of the final bracket.
    h_max : float
        Largest bound tried.

    Returns
    -------
    float
        The largest certified bound found (0 if none is).
    """
    floor = max(delay_lower)
    low, high, found = floor, math.inf, False
    count = max(2, workers())
    while math.isinf(high) or (high - low > rtol * high and high - floor > _SMALLEST):
        if math.isinf(high):  # double until a bound fails
            base = low if found else max(guess, 2.0 * floor, 1e-3)
            points = base * 2.0 ** np.arange(int(found), count + int(found))
            points = points[points <= h_max]
            if points.size == 0:
                break
        else:  # evenly spaced inside the bracket
            points = np.linspace(low, high, count + 2)[1:-1]
        _log.info("limiting vertex margin in [%.4g, %.4g] s: trying %s s", low, high,
                  ", ".join(f"{h:.4g}" for h in points))
        results = map_solves(vertex_certificate, [(params, action, h, h, method, delay_lower)
                                                  for h in points], share_cores=True)
        certified = [h for h, cert in zip(points, results, strict=True) if cert.certified]
        found = found or bool(certified)
        low = max(certified, default=low)
        high = min([h for h in points if h > low and h not in certified], default=high)
    return float(low) if found else 0.0


def cover_margin(params: TeleoperatorParams, polytope: GainPolytope, method: str = LMI_METHOD,
                 shrink: float = 0.9, attempts: int = 6, known: float = 0.0,
                 budget: int = CELL_BUDGET,
                 limit: tuple[tuple[float, ...], float] | None = None,
                 delay_lower: tuple[float, float] = NO_LOWER) -> CoverMargin:
    """Largest common delay bound ``T* = T_l* = T_r*`` certified for every constant gain of a set.

    The frozen LMI margin of the gain vertex that limits the closed form, alone (a section
    search, :func:`vertex_margin`), gives an upper limit ``L``; covers
    (:func:`cover_certificate`) are then tried at ``shrink L, shrink^2 L, ...`` and the first
    certified bound is the margin.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains, not empty.
    method : str
        A :data:`certify.METHODS` name.
    shrink : float
        Ratio between successive bounds tried, in ``(0, 1)``: the margin found is within this
        factor of the largest bound a cover certifies (if tried bounds are monotone).
    attempts : int
        Most covers tried.
    known : float
        A margin already known (for example the switching-gain margin): bounds at or below it
        are not tried, and it is returned if no cover certifies above it.
    budget : int
        Most solves per cover.
    limit : tuple, optional
        :func:`limiting_vertex` of the set (for the same ``delay_lower``), if already known.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)`` kept while ``T*`` varies.

    Returns
    -------
    CoverMargin
        The margin, the vertex limit and the cover that certifies the margin.

    Raises
    ------
    ValueError
        If the polytope is empty or ``shrink`` or ``attempts`` are out of range.
    """
    if not 0.0 < shrink < 1.0 or attempts < 1:
        raise ValueError(f"need 0 < shrink < 1 and attempts >= 1, got {shrink}, {attempts}")
    vertex, top = (limit if limit is not None
                   else limiting_vertex(params, polytope, method, delay_lower))
    solves, bound = 0, top
    for _ in range(attempts):
        bound *= shrink
        if bound <= known:
            break
        _log.info("delay margin in [%.4g, %.4g] s: trying %.4g s", known, top, bound)
        question = DelayQuestion(params, (bound, bound), delay_lower, method)
        cover = cover_certificate(question, polytope, budget)
        solves += cover.solves
        if cover.certified:
            return CoverMargin(bound, top, vertex, cover, solves)
    return CoverMargin(known, top, vertex, None, solves)
