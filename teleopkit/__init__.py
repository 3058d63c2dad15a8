"""teleopkit: delayed bilateral teleoperation with elastic joints.

Simulate the teleoperator under any delay profile, certify gain ranges with Lyapunov-Krasovskii /
LMI conditions (package :mod:`certify`), and tune the remote P+d gains with a TD3 agent whose every
action is projected into the certified set.
"""

from teleopkit import env  # noqa: F401  (registers the Gymnasium id teleopkit/FlexTeleop-v0)
from teleopkit.delays import (
    ConstantDelay,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
    parse_delay,
)
from teleopkit.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    Wall,
    paper_setup,
)
from teleopkit.scenarios import Scenario, paper_scenarios
from teleopkit.simulator import Simulator, StepResult, Trajectory, simulate

__version__ = "0.1.0"

__all__ = [
    "ConstantDelay",
    "ElasticJoints",
    "FourierDelay",
    "InitialState",
    "Operator",
    "PDGains",
    "PlanarArm",
    "Scenario",
    "Simulator",
    "SinusoidalDelay",
    "StepResult",
    "SwitchingDelay",
    "TeleoperatorParams",
    "TraceDelay",
    "Trajectory",
    "Wall",
    "paper_scenarios",
    "paper_setup",
    "parse_delay",
    "simulate",
]
