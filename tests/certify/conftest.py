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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip the certify tests marked ``slow`` unless they are selected with ``-m slow``."""
    if "slow" in (config.getoption("markexpr") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    here = str(config.rootpath / "tests" / "certify")
    for item in items:
        if "slow" in item.keywords and str(item.path).startswith(here):
            item.add_marker(skip)
