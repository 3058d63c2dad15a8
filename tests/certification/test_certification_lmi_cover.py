"""Constant gains of large sets certified by covers of cells."""

from __future__ import annotations

import numpy as np
import pytest

from certify import PolytopicDelaySystem, exact_constant_margin, max_delay
from teleopkit.certification import certify_gains
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi import systems
from teleopkit.certification.lmi.cells import CellMemo
from teleopkit.certification.lmi.cover import (
    CORNERS_AT_ONCE,
    LIMIT_RTOL,
    PROBES,
    _check_alone,
    _solve_level,
    cover_certificate,
    cover_margin,
    limiting_vertex,
    set_certificate,
    vertex_margin,
)
from teleopkit.certification.lmi.planner import Level, _split_again, clip, halves
from teleopkit.certification.lmi.systems import (
    CHANNELS,
    LMI_METHOD,
    DelayQuestion,
    lmi_certificate,
    lmi_delay_margin,
    vertex_certificate,
)
from teleopkit.certification.nuno.condition import (
    nuno_delay_margin,
    nuno_joint_margins,
    nuno_polytope,
    weakest_first,
)
from teleopkit.model.linearize import rest_systems
from teleopkit.model.params import paper_setup

NARROW = GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1)


def _ask(params, bound: float) -> DelayQuestion:
    """The LMI question for a common delay bound ``T_l* = T_r* = bound``."""
    return DelayQuestion(params, (bound, bound))


@pytest.fixture(scope="module")
def tight_cover(one_joint):
    """A bound between the switching (1.33 s) and the frozen (1.55 s) margin of NARROW."""
    return cover_certificate(_ask(one_joint, 1.45), GainPolytope.from_box(NARROW))


def test_a_bound_beyond_the_switching_margin_needs_several_cells(one_joint, tight_cover):
    whole = GainPolytope.from_box(NARROW)
    assert lmi_delay_margin(one_joint, whole, "switching").margin < 1.45
    assert tight_cover.certified and len(tight_cover.cells) > 1
    assert tight_cover.solves > len(tight_cover.cells)  # the whole set failed first
    assert all(cert.certified and cert.verify() for cert in tight_cover.certificates)


def test_the_cells_cover_the_set_and_interior_gains_are_certified(one_joint, tight_cover, rng):
    gains = rng.uniform(NARROW.lower, NARROW.upper, size=(200, 2))
    covered = np.any([cell.contains(gains, tol=1e-9) for cell in tight_cover.cells], axis=0)
    assert covered.all()
    for k, b in gains[:3]:
        point = GainPolytope.from_box(GainBox(((k, k),), ((b, b),)))
        assert lmi_certificate(one_joint, point, 1.45, 1.45).certified


def test_a_bound_beyond_a_vertex_margin_fails_at_that_vertex(one_joint):
    cover = cover_certificate(_ask(one_joint, 1.7), GainPolytope.from_box(NARROW))
    # the whole set, then the weakest corner alone, which fails: no cell is solved after it
    assert not cover.certified and "gain vertex" in cover.reason and cover.solves == 2


def test_a_failed_gain_point_in_the_memo_ends_a_cover_without_solves(one_joint):
    whole = GainPolytope.from_box(NARROW)
    first = cover_certificate(_ask(one_joint, 1.7), whole)
    memo = CellMemo(_ask(one_joint, 1.7))
    failed_point = np.array([10.0, 30.0])
    memo.record_vertex(failed_point, first.certificates[-1])
    inner = GainPolytope.from_box(GainBox(((6.0, 10.0),), ((30.0, 50.0),)))
    again = cover_certificate(_ask(one_joint, 1.7), inner, memo=memo)
    assert not again.certified and again.solves == 0 and "[10.0, 30.0]" in again.reason
    elsewhere = GainPolytope.from_box(GainBox(((5.0, 6.0),), ((50.0, 60.0),)))
    assert memo.failed_vertex(elsewhere) is None


def test_after_a_wholly_failed_level_the_next_cells_are_quarters(tight_cover):
    cover = tight_cover
    assert cover.certified and all(box is not None for box in cover.boxes)  # the root failed
    ratios = {tuple(np.round(upper / lower, 9)) for lower, upper in cover.boxes}
    assert ratios == {(np.sqrt(2).round(9),) * 2}  # both gains halved once: no halves solved
    # the root and its weakest corner alone, the next two corners after the root failed, the
    # four quarters
    assert cover.solves == 1 + 1 + CORNERS_AT_ONCE + 4


def test_a_spent_budget_is_not_certified(one_joint):
    cover = cover_certificate(_ask(one_joint, 1.45), GainPolytope.from_box(NARROW), budget=2)
    assert not cover.certified and "budget of 2 solves" in cover.reason


def test_small_sets_and_switching_gains_are_one_lmi(one_joint):
    whole = GainPolytope.from_box(NARROW)
    assert set_certificate(_ask(one_joint, 1.0), whole, "switching").solves == 1
    assert set_certificate(_ask(one_joint, 1.5), whole, "frozen").cells == (whole,)


@pytest.fixture(scope="module")
def narrow_margin(one_joint):
    return cover_margin(one_joint, GainPolytope.from_box(NARROW))


def test_the_cover_margin_lies_between_the_switching_margin_and_the_vertex_limit(
        one_joint, narrow_margin):
    whole = GainPolytope.from_box(NARROW)
    switching = lmi_delay_margin(one_joint, whole, "switching").margin
    assert narrow_margin.vertex == (10.0, 30.0)  # largest K_r, smallest B_r
    vertices = [lmi_delay_margin(one_joint, GainPolytope.from_box(GainBox(((k, k),), ((b, b),))),
                                 "frozen").margin for k, b in whole.vertices()]
    assert narrow_margin.limit == pytest.approx(min(vertices), rel=0.021 + LIMIT_RTOL)
    assert switching < narrow_margin.margin <= 0.9 * narrow_margin.limit
    cover = narrow_margin.cover
    assert cover is not None and cover.certified and narrow_margin.solves >= cover.solves
    for cert in cover.certificates:
        assert cert.verify() and cert.delay_bounds == (narrow_margin.margin,) * 2


def test_a_known_margin_above_the_vertex_limit_is_returned_without_covers(one_joint,
                                                                          narrow_margin):
    known = 1.2 * narrow_margin.limit
    result = cover_margin(one_joint, GainPolytope.from_box(NARROW), known=known)
    assert result.margin == known and result.cover is None and result.solves == 0


def test_bad_input(one_joint):
    with pytest.raises(ValueError, match="shrink"):
        cover_margin(one_joint, GainPolytope.from_box(NARROW), shrink=1.0)
    with pytest.raises(ValueError, match="budget"):
        cover_certificate(_ask(one_joint, 1.0), GainPolytope.from_box(NARROW), budget=0)
    empty = nuno_polytope(one_joint, GainBox(((40.0, 50.0),), ((1.0, 5.0),)), 1.0, 1.0)
    with pytest.raises(ValueError, match="empty"):
        cover_certificate(_ask(one_joint, 1.0), empty)


@pytest.mark.slow
def test_paper_closed_form_set_is_covered_by_the_lmi():
    """Two joints: the closed form's set at T* = 1 s, every constant gain LMI-certified."""
    params = paper_setup()
    closed = nuno_polytope(params, GainBox.uniform((1.0, 50.0), (1.0, 150.0)), 1.0, 1.0)
    cover = cover_certificate(_ask(params, 1.0), closed)
    assert cover.certified, cover.reason


@pytest.mark.slow
def test_paper_box_limiting_vertex_beats_the_closed_form_below_the_exact_margin():
    """Two joints, the whole paper box: the vertex K_r = 50, B_r = 1 limits every method."""
    params = paper_setup()
    box = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
    vertex, limit = limiting_vertex(params, GainPolytope.from_box(box))
    assert vertex == (50.0, 50.0, 1.0, 1.0)
    exact = min(exact_constant_margin(s) for s in rest_systems(params, np.asarray(vertex)))
    assert nuno_delay_margin(params, box) < limit <= exact


@pytest.mark.slow
def test_two_joint_constant_gain_margin_beats_switching_and_the_closed_form():
    """Two joints, a certified box: covers lift the margin above the one-functional bound."""
    params = paper_setup()
    box = GainBox.uniform((5.0, 10.0), (30.0, 60.0))
    cert = certify_gains(params, box, 1.0, 1.0, method="lmi")
    switching = lmi_delay_margin(params, GainPolytope.from_box(box), "switching").margin
    assert cert.certified and cert.delay_margin > max(switching, nuno_delay_margin(params, box))
    assert cert.delay_margin <= cert.details["margin_limit"]


@pytest.mark.parametrize(("action", "guess"), [((10.0, 30.0), 1.0), ((10.0, 30.0), 0.05),
                                               ((5.0, 60.0), 10.0)])
def test_the_parallel_vertex_margin_agrees_with_a_bisection(one_joint, action, guess):
    systems = PolytopicDelaySystem(tuple(rest_systems(one_joint, np.array(action))), "frozen")
    bisected = max_delay(systems, LMI_METHOD, rtol=0.01, channels=CHANNELS)
    sectioned = vertex_margin(one_joint, np.array(action), guess=guess, rtol=0.01)
    assert sectioned == pytest.approx(bisected, rel=0.021)
    assert vertex_certificate(one_joint, np.array(action), sectioned, sectioned).certified



def test_corners_checked_alone_stop_at_the_first_batch_with_a_failure(one_joint):
    memo = CellMemo(_ask(one_joint, 1.7))
    corners = GainPolytope.from_box(NARROW).vertices()
    weakest_first_order = sorted(corners.tolist(), key=lambda a: (-a[0], a[1]))  # (10, 30) first
    actions = [np.array(a) for a in weakest_first_order]
    assert _check_alone(actions, memo) == CORNERS_AT_ONCE
    assert memo.failed_vertex(GainPolytope.from_box(NARROW)) is not None
    assert memo.vertex(actions[-1]) is None  # never solved


def test_a_level_whose_most_promising_cells_fail_is_split_unsolved(one_joint, monkeypatch):
    monkeypatch.setenv("TELEOPKIT_WORKERS", "1")  # the fake solve below runs in this process
    good = vertex_certificate(one_joint, np.array([5.0, 60.0]), 0.5, 0.5)
    bad = vertex_certificate(one_joint, np.array([10.0, 30.0]), 5.0, 5.0)
    assert good.certified and not bad.certified
    whole = GainPolytope.from_box(NARROW)
    quarters = _split_again(halves((NARROW.lower, NARROW.upper)))
    todo = [(box, clip(whole, box)) for box in quarters]
    promise = [nuno_joint_margins(one_joint, cell.vertices()).min() for _, cell in todo]
    assert len(todo) == 4 > PROBES
    for verdict, solves in ((bad, PROBES), (good, len(todo))):
        calls: list[GainPolytope] = []
        monkeypatch.setattr(systems, "lmi_certificate",
                            lambda *args, v=verdict, seen=calls, **_: seen.append(args[1]) or v)
        memo = CellMemo(_ask(one_joint, 1.45))
        level = Level(todo, [None] * len(todo), list(range(len(todo))))
        solved, count = _solve_level(level, memo)
        assert count == solves
        assert len(calls) == solves and len(solved) == solves
    probed = sorted(range(len(todo)), key=lambda k: -promise[k])[:PROBES]
    assert calls[:PROBES] == [todo[k][1] for k in probed]  # the most promising first


def test_the_whole_set_is_solved_beside_its_weakest_corner(one_joint):
    polytope = GainPolytope.from_box(NARROW)
    memo = CellMemo(_ask(one_joint, 1.0))
    corners = polytope.vertices()
    weakest = corners[weakest_first(one_joint, corners)[0]]
    cover = cover_certificate(_ask(one_joint, 1.0), polytope, memo=memo)
    # one level: the set as one cell and its weakest corner alone, side by side
    assert cover.certified and len(cover.cells) == 1 and cover.solves == 2
    verdict = memo.vertex(weakest)
    assert verdict is not None and verdict.certified
    # no other corner is solved while the set is certified
    assert all(memo.vertex(c) is None for c in corners if not np.array_equal(c, weakest))
