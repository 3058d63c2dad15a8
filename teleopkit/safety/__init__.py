"""The safety layer: every remote gain is projected into a certified set before it is applied.

:func:`~teleopkit.safety.factory.layer_for` builds the layer a certificate needs, behind one
interface (:class:`~teleopkit.safety.layer.SafetyLayer`):
:class:`~teleopkit.safety.polytope.PolytopeLayer` projects exactly onto a polytope (frozen,
switching and rate-bounded gains; the compiled geometry is in :mod:`~teleopkit.safety.polygons`),
:class:`~teleopkit.safety.schedule.ScheduleLayer` onto the step's set of a scheduled class, whose
budget or tank it keeps. :class:`~teleopkit.safety.loop.CertifiedLoop` is the one control loop
that projects, then simulates, and counts actions outside the set.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "Fallback": "layer",
    "Projection": "layer",
    "SafetyLayer": "layer",
    "PolytopeLayer": "polytope",
    "ScheduleLayer": "schedule",
    "layer_for": "factory",
    "CertifiedLoop": "loop",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
