"""Reference systems shared by the certify tests."""

from __future__ import annotations

import numpy as np
import pytest

from certify import LinearDelaySystem


@pytest.fixture(scope="session")
def benchmark_system() -> LinearDelaySystem:
    """``A = [[-2,0],[0,-0.9]]``, ``Ad = [[-1,0],[-1,-1]]`` (Fridman & Shaked et al.)."""
    return LinearDelaySystem(
        np.array([[-2.0, 0.0], [0.0, -0.9]]), [np.array([[-1.0, 0.0], [-1.0, -1.0]])]
    )


@pytest.fixture(scope="session")
def scalar_system() -> LinearDelaySystem:
    """``x' = -x(t - tau)``."""
    return LinearDelaySystem(0.0, [-1.0])

