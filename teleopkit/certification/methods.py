"""The certification methods and the one that answers a question with each.

``"nuno"`` is the closed form of :mod:`teleopkit.certification.nuno` (nonlinear model, frozen
and scheduled gains, instant); ``"lmi"`` the Lyapunov–Krasovskii LMIs of
:mod:`teleopkit.certification.lmi` on the linearisation at rest (frozen, switching and
rate-bounded gains; seconds for one joint, a minute or two for two); ``"all"`` every method
that covers the gain class. :func:`certify_with` runs one method; the entry point
:func:`~teleopkit.certification.certifier.certify_gains` adds the choice among methods, the
worker processes and the cache.
"""

from __future__ import annotations

from collections.abc import Callable

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.nuno.condition import certify_frozen
from teleopkit.certification.nuno.scheduled import certify_scheduled
from teleopkit.model.params import TeleoperatorParams

__all__ = ["METHODS", "best_certificate", "certify_with", "methods_for"]

METHODS = ("nuno", "lmi", "all")
"""Values of ``method`` accepted by :func:`~teleopkit.certification.certifier.certify_gains`."""


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
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
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


def certify_with(name: str, params: TeleoperatorParams, box: GainBox, tl_max: float,
                 tr_max: float, variation: GainVariation,
                 delay_lower: tuple[float, float] = (0.0, 0.0),
                 on_proven: Callable[[GainCertificate], None] | None = None) -> GainCertificate:
    """The answer of one method (``"nuno"`` or ``"lmi"``), checked inputs assumed.

    The closed form covers every delay in ``[0, T_i*]``, hence any minimum delay
    (``delay_lower`` is not needed and its certificate records 0); the LMIs use it.

    Parameters
    ----------
    name : {"nuno", "lmi"}
        The method.
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : GainVariation
        Gain class.
    delay_lower : tuple of float
        Minimum delays in seconds.
    on_proven : callable, optional
        The LMI method hands it each larger set proven on the way
        (:func:`~teleopkit.certification.lmi.verdict.certify_lmi`); unused by the closed form,
        which answers at once.

    Returns
    -------
    GainCertificate
        The method's certificate.
    """
    if name == "lmi":
        from teleopkit.certification.lmi.verdict import certify_lmi  # cvxpy: only when asked

        return certify_lmi(params, box, tl_max, tr_max, variation, delay_lower,
                           on_proven=on_proven)
    if name != "nuno":
        raise ValueError(f"unknown method {name!r}; available: nuno, lmi")
    certify = certify_scheduled if variation.scheduled else certify_frozen
    return certify(params, box, tl_max, tr_max, variation)
