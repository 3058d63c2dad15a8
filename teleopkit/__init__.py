"""teleopkit: delayed bilateral teleoperation with elastic joints.

Simulate the teleoperator under any delay profile, certify gain ranges with Lyapunov-Krasovskii /
LMI conditions (package :mod:`certify`), and tune the remote P+d gains with a TD3 agent whose every
action is projected into the certified set.

The layers, each a sub-package, from the bottom up: :mod:`teleopkit.model` (parameters,
dynamics, P+d laws, linearisation), :mod:`teleopkit.delays` (delay profiles and channel
histories), :mod:`teleopkit.sim` (scenarios, the simulator, metrics) with beside it
:mod:`teleopkit.setup` (a user's plant, network, operator and start, read from a setup file,
which draws the scenarios), :mod:`teleopkit.certification`
(gain sets and their certificates), :mod:`teleopkit.safety` (the projection of every gain onto a
certified set), :mod:`teleopkit.rl` (environments, TD3, training and evaluation) and
:mod:`teleopkit.robustness` (campaigns and falsification). The names below load on first use,
so ``import teleopkit`` stays fast; it also registers the Gymnasium id
``teleopkit/FlexTeleop-v0``.
"""

from teleopkit._lazy import lazy_namespace
from teleopkit._version import __version__ as __version__
from teleopkit.rl.registration import register

_EXPORTS = {
    **{name: "model.params" for name in (
        "ElasticJoints", "InitialState", "Operator", "PDGains", "PlanarArm", "TeleoperatorParams",
        "Wall", "paper_setup")},
    **{name: "delays.profiles" for name in (
        "ConstantDelay", "FourierDelay", "SinusoidalDelay", "SwitchingDelay", "TraceDelay")},
    "parse_delay": "delays.spec",
    "Scenario": "sim.scenarios",
    "Setup": "setup",
    "SetupError": "setup",
    "paper_scenarios": "sim.scenarios",
    "Simulator": "sim.simulator",
    "simulate": "sim.simulator",
    "StepResult": "sim.trajectory",
    "Trajectory": "sim.trajectory",
    "GainBox": "certification.gain_sets",
    "GainCertificate": "certification.gain_certificate",
    "certify_gains": "certification.certifier",
    "SafetyLayer": "safety.layer",
    "layer_for": "safety.factory",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)

register()
