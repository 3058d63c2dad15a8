"""The safety layer: every remote gain is projected into a certified set before it is applied.

:class:`~teleopkit.safety.layer.SafetyLayer` projects raw gains exactly onto a certificate's set
(the compiled geometry is in :mod:`~teleopkit.safety.polygons`), and
:class:`~teleopkit.safety.loop.CertifiedLoop` is the one control loop that projects, then
simulates, and counts actions outside the set.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "Fallback": "layer",
    "Projection": "layer",
    "SafetyLayer": "layer",
    "CertifiedLoop": "loop",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
