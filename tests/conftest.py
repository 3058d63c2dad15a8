"""Shared fixtures."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    paper_setup,
)


@pytest.fixture
def params():
    return paper_setup()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def one_joint() -> TeleoperatorParams:
    """The paper's first joint alone (same arm, spring, rotor and gains): cheap LMIs."""
    arm = PlanarArm((0.38,), (0.5,))
    return TeleoperatorParams(
        local_arm=arm, remote_arm=arm, joints=ElasticJoints((100.0,), (0.3,)),
        local_gains=PDGains((25.0,), (10.0,)), remote_gains=PDGains((10.0,), (30.0,)),
        operator=Operator(amplitudes=(3.0,), frequencies=(1.0,), phases=(0.0,), decays=(0.05,)),
        initial=InitialState((-0.2,), (-0.1,), (0.0,)))



def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip the tests marked ``slow`` unless they are selected with ``-m slow``."""
    if "slow" in (config.getoption("markexpr") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
