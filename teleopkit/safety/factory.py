"""The one way from a certificate to its safety layer."""

from __future__ import annotations

import math

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.safety.layer import SafetyLayer
from teleopkit.safety.polytope import PolytopeLayer
from teleopkit.safety.schedule import ScheduleLayer

__all__ = ["layer_for"]


def layer_for(certificate: GainCertificate, period: float = 0.01, rate: float | None = None,
              tol: float = 1e-9) -> SafetyLayer:
    """The safety layer that enforces a certificate's set and gain class.

    The set is the certificate's: its polytope (the certified subset of the box asked about,
    accepted when it is certified even if the whole box is not) for the frozen, switching and
    rate-bounded classes, its :class:`~teleopkit.certification.scheduled_set.ScheduledSet` for
    the scheduled ones. A certificate whose set is not certified is refused.

    Parameters
    ----------
    certificate : GainCertificate
        Verdict and set, for example from :func:`~teleopkit.certification.certify_gains`.
    period : float
        Control period ``T_s`` in seconds (converts a rate into a per-step bound).
    rate : float, optional
        Largest gain rate ``rho`` (gain units per second). Defaults to the certificate's rate
        for ``gain_variation = "rate:R"`` and to no bound otherwise; it may tighten the
        certificate's rate, never loosen it.
    tol : float
        Tolerance of the active-constraint report.

    Returns
    -------
    SafetyLayer
        A :class:`~teleopkit.safety.polytope.PolytopeLayer` (rate-bounded if asked) or, for a
        scheduled class, a :class:`~teleopkit.safety.schedule.ScheduleLayer`.

    Raises
    ------
    ValueError
        If the certificate does not certify its set, the set is empty, or the rate exceeds the
        certified one.

    Examples
    --------
    >>> import numpy as np
    >>> from teleopkit.certification import default_certificate
    >>> layer = layer_for(default_certificate())
    >>> result = layer.step(np.array([40.0, 10.0, 60.0, 30.0]))
    >>> result.action.round(3).tolist(), bool(result.fallback)
    ([26.207, 10.0, 65.517, 30.0], False)
    """
    if not certificate.polytope_certified:
        raise ValueError(f"the {certificate.method} certificate does not certify its gain "
                         f"set ({certificate.violation or 'not certified'}); refusing to "
                         "build a safety layer on it")
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"control period must be positive, got {period}")
    variation = certificate.variation
    if variation.scheduled:
        return ScheduleLayer(certificate, tol)
    chosen = variation.rate if rate is None else float(rate)
    if chosen > variation.rate:
        raise ValueError(f"rate bound {chosen:g}/s exceeds the certified {variation.rate:g}/s")
    layer = PolytopeLayer(certificate.polytope, None if math.isinf(chosen) else chosen * period,
                          tol)
    layer.certificate = certificate
    return layer
