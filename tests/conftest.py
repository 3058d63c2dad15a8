"""Shared fixtures."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.params import paper_setup


@pytest.fixture
def params():
    return paper_setup()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
