"""The comparators without learning: semi-active damping law and open-loop schedules."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.controllers import ConstantGains, GainSchedule, SemiActiveDamping
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.scoring import OBSERVATION

N = 2


def observation(deflection: list[float], extra: int = 0) -> np.ndarray:
    obs = np.zeros((1, len(OBSERVATION) * N + extra))
    start = OBSERVATION.index("e_damp") * N
    obs[0, start:start + N] = deflection
    return obs


def test_the_semi_active_law_damps_a_growing_deflection_only():
    law = SemiActiveDamping(4.0, 10.0, 60.0)
    law.reset()
    np.testing.assert_array_equal(law(observation([0.1, -0.1])), [[4, 4, 10, 10]])
    np.testing.assert_array_equal(law(observation([0.2, -0.05])), [[4, 4, 60, 10]])
    np.testing.assert_array_equal(law(observation([-0.3, 0.2], extra=3)), [[4, 4, 60, 60]])
    np.testing.assert_array_equal(law(observation([0.0, 0.1], extra=3)), [[4, 4, 10, 10]])
    law.reset()  # a new episode starts low
    np.testing.assert_array_equal(law(observation([0.5, 0.5])), [[4, 4, 10, 10]])


def test_the_semi_active_law_refuses_inverted_levels():
    with pytest.raises(ValueError, match="B_low <= B_high"):
        SemiActiveDamping(4.0, 50.0, 10.0)


def test_a_schedule_replays_its_rows_then_holds_the_last():
    schedule = GainSchedule(np.array([[1.0, 1, 3, 3], [2.0, 2, 5, 5]]))
    obs = np.zeros((3, 14))
    schedule.reset()
    rows = [schedule(obs)[0].tolist() for _ in range(3)]
    assert rows == [[1, 1, 3, 3], [2, 2, 5, 5], [2, 2, 5, 5]]
    schedule.reset()
    assert schedule(obs)[0].tolist() == [1, 1, 3, 3]
    with pytest.raises(ValueError, match="finite gains"):
        GainSchedule(np.array([[np.nan, 1, 1, 1]]))


def test_stateful_controllers_are_reset_by_every_rollout():
    """The same controller gives the same run twice (its state does not leak across runs)."""
    config = FlexTeleopConfig(certificate=default_certificate(variation="scheduled:0"),
                              episode_length=0.5)
    law = SemiActiveDamping(5.0, 13.0, 80.0)
    first, second = rollout(law, 2, 3, config), rollout(law, 2, 3, config)
    np.testing.assert_array_equal(first.applied, second.applied)
    table = first.metrics()
    assert first.unsafe_actions == 0 and table["covered"].all()
    np.testing.assert_array_equal(first.applied[..., :2], 5.0)  # the stiffness never moves
    assert set(np.unique(first.applied[..., 2:])) == {13.0, 80.0}
    assert np.any(first.applied[..., 2:] > 79.0)  # and the high level is used
    constant = rollout(ConstantGains(np.array([5.0, 5.0, 13.0, 13.0])), 2, 3, config)
    assert constant.metrics()["gain_changes"].eq(0).all()
