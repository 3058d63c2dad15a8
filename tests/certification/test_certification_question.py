"""A certification question is one value, checked once, keyed for the cache."""

from __future__ import annotations

import pytest

from teleopkit.certification.gain_classes import parse_gain_variation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.methods import certify_with
from teleopkit.certification.question import Question
from teleopkit.model.params import paper_setup

BOX = GainBox.uniform((5.0, 10.0), (30.0, 60.0))


def test_it_parses_and_checks_its_parts_once():
    question = Question(paper_setup(), BOX, (1.0, 0.8), (0.1, 0.0), "tank:3")
    assert question.gain_class == parse_gain_variation("tank:3")
    assert question.bounds == (1.0, 0.8) and question.lower == (0.1, 0.0)
    with pytest.raises(ValueError, match="gain box has 1 joints, the teleoperator 2"):
        Question(paper_setup(), GainBox.uniform((5.0, 10.0), (30.0, 60.0), 1))
    with pytest.raises(ValueError, match="K_r of joint 1 is 0 everywhere"):
        Question(paper_setup(), GainBox.uniform((0.0, 0.0), (30.0, 60.0)))
    with pytest.raises(ValueError):
        Question(paper_setup(), BOX, (1.0, -1.0))


def test_its_key_names_every_part_and_the_method():
    base = Question(paper_setup(), BOX)
    keys = {base.key("nuno"), base.key("lmi"), Question(paper_setup(), BOX, (1.0, 0.9)).key("lmi"),
            Question(paper_setup(), BOX, variation="switching").key("lmi"),
            Question(paper_setup(), GainBox.uniform((5.0, 9.0), (30.0, 60.0))).key("lmi")}
    assert len(keys) == 5 and base.key("lmi") == Question(paper_setup(), BOX).key("lmi")


def test_a_method_answers_the_question():
    answer = certify_with("nuno", Question(paper_setup(), BOX))
    assert answer.certified and answer.delay_margin == pytest.approx(1.0954, abs=1e-4)
    with pytest.raises(ValueError, match="unknown method 'spectrum'"):
        certify_with("spectrum", Question(paper_setup(), BOX))
