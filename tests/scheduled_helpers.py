"""Plants, adversarial delays and certificates shared by the tests of the scheduled gain classes.

Imported by tests/certification (nuno.lyapunov, nuno.scheduled), tests/safety (schedule) and
tests/rl (torch_projection); ``tests/`` is on ``sys.path`` through ``tests/conftest.py``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from teleopkit.certification import GainBox, GainCertificate, certify_gains
from teleopkit.delays import SwitchingDelay
from teleopkit.model.params import Operator, PDGains, paper_setup
from teleopkit.sim import Scenario, Simulator

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0))
PASSIVE = dataclasses.replace(paper_setup(), operator=Operator(amplitudes=(0.0, 0.0)),
                              torque_limit=math.inf)
"""The paper's plant with the operator holding the origin (passive) and no torque saturation."""
SHAPED = dataclasses.replace(PASSIVE, local_gains=PDGains((25.0, 15.0), (10.0, 8.0)))
"""Different local gains per joint: the common shape is then (1, 0.6)."""


def adversarial(params, batch: int = 6, seed: int = 0) -> Simulator:
    """Delays jumping between 0 and 1 s every 50-70 ms, both channels independently."""
    return Simulator(Scenario(params, SwitchingDelay(0.0, 1.0, 0.06, "extremes", seed, batch),
                              SwitchingDelay(0.0, 1.0, 0.05, "extremes", seed + 1, batch),
                              np.ones((batch, params.n_joints))))


def certified(variation: str, params=PASSIVE) -> GainCertificate:
    return certify_gains(params, BOX, 1.0, 1.0, "nuno", variation)
