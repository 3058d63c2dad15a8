"""Tests of teleopkit.delays.spec: delay profiles from the command line's short text specs."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.delays import parse_delay


@pytest.mark.parametrize("spec", ["", "paperx", "constant", "constant:a", "sine:1:2",
                                  "constant:-1", "sine:0.1:0.5:1", "csv:"])
def test_bad_delay_specs_are_refused(spec):
    with pytest.raises(ValueError):
        parse_delay(spec)


def test_delay_specs():
    forward, backward = parse_delay("constant:0.25")
    assert forward.bound == backward.bound == 0.25
    forward, backward = parse_delay("switching:0:1:0.01", np.random.default_rng(0))
    assert forward.seed != backward.seed
    forward, _ = parse_delay("paper", np.random.default_rng(0))
    assert 0.5 <= float(forward.scale[0]) <= 1.0
