"""Covers of nested gain sets share their cells' verdicts (``CellMemo``), soundly."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.cells import CellMemo
from teleopkit.certification.lmi.cover import cover_certificate
from teleopkit.certification.lmi.proof import check_proof, cover_proof
from teleopkit.certification.lmi.systems import DelayQuestion

BOUND = 1.45  # between the switching (1.33 s) and the frozen (1.55 s) margin of the box
WHOLE = GainPolytope.from_box(GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1))
# the box with its weakest corner (K_r = 10, B_r = 30) cut off: same bounding box, a subset
CUT = WHOLE.intersect(np.array([[1.0, -0.1]]), np.array([6.9]), ("corner cut",))


def _ask(params) -> DelayQuestion:
    return DelayQuestion(params, (BOUND, BOUND))


def _memo(params) -> CellMemo:
    return CellMemo(_ask(params))


def _sound(params, polytope, cover) -> None:
    """Every cell's certificate holds, and the cover's proof checks from the plant alone."""
    assert cover.certified and all(cert.verify() for cert in cover.certificates)
    check_proof(params, polytope, cover_proof(cover, (BOUND, BOUND)), (BOUND, BOUND),
                 ("switching",))


@pytest.fixture(scope="module")
def fresh(one_joint):
    """Both sets covered without a memo: the solves each costs alone."""
    return {name: cover_certificate(_ask(one_joint), polytope)
            for name, polytope in (("whole", WHOLE), ("cut", CUT))}


@pytest.mark.parametrize(("first", "then"), [("whole", "cut"), ("cut", "whole")],
                         ids=["a subset reuses certified cells", "a superset skips failed ones"])
def test_a_second_cover_of_a_nested_set_costs_fewer_solves(one_joint, fresh, first, then):
    sets = {"whole": WHOLE, "cut": CUT}
    memo = _memo(one_joint)
    cover_certificate(_ask(one_joint), sets[first], memo=memo)
    second = cover_certificate(_ask(one_joint), sets[then], memo=memo)
    _sound(one_joint, sets[then], second)
    assert second.solves < fresh[then].solves


def test_recall_goes_by_inclusion_only(one_joint, fresh):
    memo = _memo(one_joint)
    box = (np.array([5.0, 30.0]), np.array([10.0, 60.0]))  # the bounding box of both sets
    assert memo.recall(box, CUT) is None  # nothing known yet
    cover_certificate(_ask(one_joint), CUT, memo=memo)
    assert fresh["cut"].solves > 1  # the cut as one cell failed, so the whole box fails too
    recalled = memo.recall(box, WHOLE)
    assert recalled is not None and not recalled.certified
    other = (box[0], box[1] + 1.0)  # another box: no verdict carries over
    assert memo.recall(other, WHOLE) is None


def test_a_memo_of_another_question_is_refused(one_joint):
    other = CellMemo(DelayQuestion(one_joint, (1.0, 1.0)))
    with pytest.raises(ValueError, match="another question"):
        cover_certificate(_ask(one_joint), WHOLE, memo=other)


ROOT = (np.array([5.0, 30.0]), np.array([10.0, 60.0]))
# a subset with another bounding box (K_r from 5.5): covered from the same root, its boxes line up
STRIP = WHOLE.intersect(np.array([[-1.0, 0.0]]), np.array([-5.5]), ("K_r >= 5.5",))


def test_sets_with_other_bounding_boxes_share_cells_split_from_one_root(one_joint):
    fresh = cover_certificate(_ask(one_joint), STRIP, root=ROOT)
    memo = _memo(one_joint)
    cover_certificate(_ask(one_joint), WHOLE, memo=memo, root=ROOT)
    strip = cover_certificate(_ask(one_joint), STRIP, memo=memo, root=ROOT)
    _sound(one_joint, STRIP, strip)
    assert strip.solves < fresh.solves


def test_a_proof_s_root_must_contain_the_set(one_joint):
    cover = cover_certificate(_ask(one_joint), STRIP, root=ROOT)
    proof = cover_proof(cover, (BOUND, BOUND))
    assert proof["root"] == [ROOT[0].tolist(), ROOT[1].tolist()]
    shrunk = {**proof, "root": [[6.0, 30.0], [10.0, 60.0]]}  # misses K_r in [5.5, 6]
    with pytest.raises(ValueError, match="root box"):
        check_proof(one_joint, STRIP, shrunk, (BOUND, BOUND), ("switching",))
    with pytest.raises(ValueError, match="outside the root box"):
        cover_certificate(_ask(one_joint), WHOLE, root=(ROOT[0] + 1.0, ROOT[1]))
