"""Certification of remote gain sets: gain sets, gain classes, certificates and their methods.

:func:`~teleopkit.certification.analysis.certify_gains` is the entry point: a
:class:`~teleopkit.certification.gain_sets.GainBox` and delay bounds in, a
:class:`~teleopkit.certification.certificate.GainCertificate` out. The methods are the closed
form of Nuño et al. (:mod:`~teleopkit.certification.closed_form`) and Lyapunov–Krasovskii LMIs
on the linearisation at rest (:mod:`~teleopkit.certification.lmi` builds the delay systems,
:mod:`~teleopkit.certification.cover` covers large sets of constant gains with cells,
:mod:`~teleopkit.certification.lmi_verdict` turns them into a certificate). Gain classes are in
:mod:`~teleopkit.certification.classes`, delay bounds in :mod:`~teleopkit.certification.bounds`,
and :mod:`~teleopkit.certification.report` prints certificates as text.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "GainBox": "gain_sets",
    "GainPolytope": "gain_sets",
    "parse_range": "gain_sets",
    "GainVariation": "classes",
    "parse_gain_variation": "classes",
    "GainCertificate": "certificate",
    "DEFAULT_BOX": "analysis",
    "best_certificate": "analysis",
    "certify_gains": "analysis",
    "default_certificate": "analysis",
    "methods_for": "analysis",
    "certificate_table": "report",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
