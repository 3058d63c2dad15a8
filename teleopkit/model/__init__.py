"""The teleoperator's model: parameters, rigid-body dynamics, P+d laws and the linearisation.

Parameters are frozen dataclasses (:mod:`teleopkit.model.params`), never changed during a run;
:mod:`~teleopkit.model.records` writes the plant a certificate depends on as JSON-ready data.
:mod:`~teleopkit.model.dynamics` gives the inertia, Coriolis matrix and energies of planar arms,
:mod:`~teleopkit.model.laws` the controllers, operator and environment torques, and
:mod:`~teleopkit.model.linearize` the closed loop linearised at rest as a delay system for
:mod:`certify`.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    name: "params" for name in (
        "ElasticJoints", "InitialState", "Operator", "PDGains", "PlanarArm", "TeleoperatorParams",
        "Wall", "one_joint_setup", "paper_setup")
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
