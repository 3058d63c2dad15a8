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


@pytest.fixture(autouse=True, scope="session")
def private_cache(tmp_path_factory):
    """Certificates and comparators found by the tests go to a temporary cache, never ~/.cache."""
    import os

    previous = os.environ.get("TELEOPKIT_CACHE")
    os.environ["TELEOPKIT_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if previous is None:
        os.environ.pop("TELEOPKIT_CACHE", None)
    else:
        os.environ["TELEOPKIT_CACHE"] = previous


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


@pytest.fixture(scope="module")
def policy():
    """A TD3 policy sized for the paper's plant, some of its gains outside the certified set.

    Used by tests/rl (evaluation) and tests/cli (tuning); torch is imported only when asked for.
    """
    import torch

    from teleopkit.rl.env import FlexTeleopConfig, FlexTeleopVectorEnv
    from teleopkit.rl.td3 import TD3

    agent = TD3.for_env(FlexTeleopVectorEnv(1, FlexTeleopConfig(episode_length=0.3)), seed=0)
    with torch.no_grad():
        agent.actor.head.bias.copy_(torch.tensor([2.0, -1.0, -3.0, 1.0]))  # some outside the set
    return agent.policy({"best_static_gains": [3.0, 7.0, 8.0, 18.0]})



def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip the tests marked ``slow`` unless they are selected with ``-m slow``."""
    if "slow" in (config.getoption("markexpr") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
