"""The certification methods and the one that answers a question with each.

``"nuno"`` is the closed form of :mod:`teleopkit.certification.nuno` (nonlinear model, frozen
and scheduled gains, instant); ``"lmi"`` the Lyapunov–Krasovskii LMIs of
:mod:`teleopkit.certification.lmi` on the linearisation at rest (frozen, switching and
rate-bounded gains; seconds for one joint, a minute or two for two); ``"all"`` every method
that covers the gain class. :func:`certify_with` answers a
:class:`~teleopkit.certification.question.Question` with one method; the entry point
:func:`~teleopkit.certification.certifier.certify_gains` adds the choice among methods, the
worker processes and the cache.
"""

from __future__ import annotations

from collections.abc import Callable

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.nuno.condition import certify_frozen
from teleopkit.certification.nuno.scheduled import certify_scheduled
from teleopkit.certification.question import Question

__all__ = ["CERTIFIERS", "best_certificate", "certify_with", "methods_for"]

CERTIFIERS = ("nuno", "lmi", "all")
"""Values of ``method`` accepted by :func:`~teleopkit.certification.certifier.certify_gains`
(the LMI formulations of the package :mod:`certify` are ``certify.METHODS``)."""


def methods_for(method: str, variation: GainVariation) -> tuple[str, ...]:
    """The single methods that ``method`` runs for a gain class (``"all"`` expands).

    Parameters
    ----------
    method : {"nuno", "lmi", "all"}
        Requested method.
    variation : GainVariation
        Gain class: the closed form covers frozen and scheduled gains, the LMIs frozen,
        switching and rate-bounded ones.

    Returns
    -------
    tuple of str
        Method names.
    """
    if method not in CERTIFIERS:
        raise ValueError(f"unknown method {method!r}; available: {', '.join(CERTIFIERS)}")
    if method != "all":
        return (method,)
    if variation.scheduled:
        return ("nuno",)
    return ("lmi", "nuno") if variation.kind == "frozen" else ("lmi",)


def best_certificate(certificates: list[GainCertificate]) -> GainCertificate:
    """The most useful of several certificates of one question.

    Certified before not certified, then a certified polytope, then the larger delay margin.
    For frozen gains every method certifies pointwise, so the best one alone is sound.

    Parameters
    ----------
    certificates : list of GainCertificate
        Answers of different methods to the same question.

    Returns
    -------
    GainCertificate
        The best of them.
    """
    return max(certificates, key=lambda c: (c.certified, c.polytope_certified, c.delay_margin))


def _closed_form(question: Question,
                 on_proven: Callable[[GainCertificate], None] | None) -> GainCertificate:
    """The closed form: frozen gains pointwise, or a scheduled class's storage."""
    variation = question.gain_class
    certify = certify_scheduled if variation.scheduled else certify_frozen
    return certify(question.params, question.box, *question.bounds, variation)


def _lmi(question: Question,
         on_proven: Callable[[GainCertificate], None] | None) -> GainCertificate:
    """The LMIs on the linearisation (cvxpy is imported only when asked)."""
    from teleopkit.certification.lmi.verdict import certify_lmi

    return certify_lmi(question, on_proven=on_proven)


_METHODS: dict[str, Callable[[Question, Callable[[GainCertificate], None] | None],
                             GainCertificate]] = {"nuno": _closed_form, "lmi": _lmi}


def certify_with(name: str, question: Question,
                 on_proven: Callable[[GainCertificate], None] | None = None) -> GainCertificate:
    """The answer of one method to a question.

    The closed form covers every delay in ``[0, T_i*]``, hence any minimum delay (its
    certificate records 0); the LMIs use the question's minimum delays.

    Parameters
    ----------
    name : {"nuno", "lmi"}
        The method.
    question : Question
        What to certify.
    on_proven : callable, optional
        The LMI method hands it each larger set proven on the way
        (:func:`~teleopkit.certification.lmi.verdict.certify_lmi`); unused by the closed form,
        which answers at once.

    Returns
    -------
    GainCertificate
        The method's certificate.
    """
    method = _METHODS.get(name)
    if method is None:
        raise ValueError(f"unknown method {name!r}; available: {', '.join(_METHODS)}")
    return method(question, on_proven)
