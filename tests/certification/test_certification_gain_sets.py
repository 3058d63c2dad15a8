"""Tests of teleopkit.certification.gain_sets: gain ranges, boxes and polytopes."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.certification import load_certificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope, parse_range
from teleopkit.certification.nuno.condition import nuno_polytope
from teleopkit.model.params import paper_setup

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))


@pytest.mark.parametrize(("text", "expected"), [("1:50", (1.0, 50.0)), ("7", (7.0, 7.0)),
                                                ("0:0.5", (0.0, 0.5))])
def test_parse_range(text, expected):
    assert parse_range(text, "--kr") == expected


@pytest.mark.parametrize(("text", "message"), [
    ("50:1", "inverted"), ("-1:5", "non-negative"), ("nan:5", "finite"), ("1:inf", "finite"),
    ("a:b", "numbers"), ("1:2:3", "MIN:MAX"), ("", "numbers"),
])
def test_bad_ranges(text, message):
    with pytest.raises(ValueError, match=message):
        parse_range(text, "--kr")


def test_empty_polytope_and_round_trip():
    params = paper_setup()
    tight = nuno_polytope(params, GainBox.uniform((40, 50), (1, 2)), 1.0, 1.0)
    assert tight.is_empty()
    polytope = nuno_polytope(params, BOX, 0.5, 0.5)
    again = GainPolytope.from_dict(polytope.to_dict())
    np.testing.assert_array_equal(again.G, polytope.G)
    assert again.labels == polytope.labels
    with pytest.raises(ValueError, match="malformed"):
        GainPolytope.from_dict({"G": [[1.0]]})


def test_certificate_json_round_trip_and_malformed():
    from teleopkit.certification import certify_gains

    cert = certify_gains(paper_setup(), BOX, 0.05, 0.05, method="nuno")
    assert cert.certified
    again = load_certificate(cert.to_json())
    assert again.to_dict() == cert.to_dict()
    with pytest.raises(ValueError, match="malformed gain certificate"):
        load_certificate('{"certified": true}')
    with pytest.raises(ValueError, match="malformed gain certificate"):
        load_certificate("not json")
