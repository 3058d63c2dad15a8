"""Fixtures shared by the rl tests."""

from __future__ import annotations

import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.safety.factory import layer_for


@pytest.fixture(scope="module")
def layer():
    return layer_for(default_certificate())
