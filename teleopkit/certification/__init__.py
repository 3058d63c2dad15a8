"""Certification of remote gain sets: gain sets, gain classes, certificates and their methods.

:func:`~teleopkit.certification.certifier.certify_gains` is the entry point: a
:class:`~teleopkit.certification.gain_sets.GainBox` and delay bounds in, a
:class:`~teleopkit.certification.gain_certificate.GainCertificate` out. The methods are the closed
form of Nuño et al. (:mod:`~teleopkit.certification.nuno.condition`) and Lyapunov–Krasovskii LMIs
on the linearisation at rest (:mod:`~teleopkit.certification.lmi.systems` builds the delay systems,
:mod:`~teleopkit.certification.lmi.cover` covers large sets of constant gains with cells,
:mod:`~teleopkit.certification.lmi.verdict` turns them into a certificate). Gain classes are in
:mod:`~teleopkit.certification.gain_classes`, delay bounds in
:mod:`~teleopkit.certification.delay_bounds`, and :mod:`~teleopkit.certification.report` prints
certificates as text.
"""

from teleopkit._lazy import lazy_namespace

_EXPORTS = {
    "GainBox": "gain_sets",
    "GainPolytope": "gain_sets",
    "parse_range": "gain_sets",
    "GainVariation": "gain_classes",
    "parse_gain_variation": "gain_classes",
    "GainCertificate": "gain_certificate",
    "DEFAULT_BOX": "certifier",
    "certify_all": "certifier",
    "certify_gains": "certifier",
    "default_certificate": "certifier",
    "CERTIFIERS": "methods",
    "Question": "question",
    "best_certificate": "methods",
    "methods_for": "methods",
    "certificate_table": "report",
    "check_certificate": "verification",
    "cover_plants": "verification",
    "load_certificate": "verification",
    "verify_certificate": "verification",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _EXPORTS)
