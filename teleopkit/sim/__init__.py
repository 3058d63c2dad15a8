"""Simulation: scenarios, the state layout, the batched simulator, its integrators and metrics.

A :class:`~teleopkit.sim.scenarios.Scenario` is a teleoperator, its delay profiles and the
operator's reference gains for a batch of runs. :class:`~teleopkit.sim.simulator.Simulator`
integrates it with the compiled kernel (:mod:`~teleopkit.sim.kernel`) or the readable numpy
integrator (:mod:`~teleopkit.sim.numpy_integrator`), holding the remote gains over each control
period (:mod:`~teleopkit.sim.timing`). States follow :mod:`~teleopkit.sim.state`; runs come back as
:mod:`~teleopkit.sim.trajectory` objects, reduced by :mod:`~teleopkit.sim.metrics` and judged by
the one divergence criterion of :mod:`~teleopkit.sim.divergence`.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "Scenario": "scenarios",
    "paper_scenarios": "scenarios",
    "sample_reference_gains": "scenarios",
    "StateLayout": "state",
    "Simulator": "simulator",
    "simulate": "simulator",
    "StepResult": "trajectory",
    "Trajectory": "trajectory",
    "CONTROL_PERIOD": "timing",
    "DEFAULT_DT": "timing",
    "Divergence": "divergence",
    "DivergenceWarning": "divergence",
    "RunningMetrics": "metrics",
    "error_metrics": "metrics",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
