"""Gain classes as text: every number a class takes is checked, NaN never reads as "none"."""

from __future__ import annotations

import math

import pytest

from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation


@pytest.mark.parametrize("text", ["frozen", "switching", "rate:2", "scheduled:0.5", "tank",
                                  "tank:3", "tank:0.5rad"])
def test_a_class_reads_back_as_it_prints(text):
    assert str(parse_gain_variation(text)) == text
    assert parse_gain_variation(str(parse_gain_variation(text))) == parse_gain_variation(text)


def test_a_tank_without_a_number_starts_empty():
    assert parse_gain_variation("tank") == GainVariation("tank", 0.0)


@pytest.mark.parametrize(("text", "number"), [
    ("rate:nan", "nan"), ("scheduled:nan", "nan"), ("tank:nan", "nan"),
    ("tank:nanrad", "nanrad"), ("tank:NaN", "NaN"), ("rate:-nan", "-nan"), ("tank:x", "x")])
def test_nan_in_any_class_is_refused_quoting_what_was_typed(text, number):
    with pytest.raises(ValueError) as error:
        parse_gain_variation(text)
    assert str(error.value) == f"gain variation {text!r}: {number!r} is not a number"


@pytest.mark.parametrize("text", ["frozen:nan", "switching:nan"])
def test_a_class_without_a_number_refuses_nan_too(text):
    with pytest.raises(ValueError, match=f"takes no number, got {text!r}"):
        parse_gain_variation(text)


@pytest.mark.parametrize(("kind", "unit", "message"), [
    ("rate", "", "positive finite rate, got nan"),
    ("scheduled", "", "finite log budget L >= 0, got nan"),
    ("tank", "rad", "positive finite deflection, got nan rad"),
])
def test_a_class_built_with_nan_is_refused_naming_nan(kind, unit, message):
    with pytest.raises(ValueError, match=message):
        GainVariation(kind, math.nan, unit)


@pytest.mark.parametrize(("text", "message"), [
    ("tank:-3", "got -3"), ("tank:inf", "got inf"), ("tank:infrad", "got inf rad"),
    ("rate:inf", "got inf"), ("scheduled:-1", "got -1")])
def test_numbers_outside_a_class_are_refused_with_the_number(text, message):
    with pytest.raises(ValueError, match=message):
        parse_gain_variation(text)
