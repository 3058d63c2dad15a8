"""Certify remote gain ranges of the teleoperator for given delay bounds.

:func:`certify_gains` answers "is every gain in this box stable for delays up to ``T_l*, T_r*``?"
with a :class:`~teleopkit.certification.gain_certificate.GainCertificate`: the verdict, the
admissible polytope inside the box (what the safety layer projects onto), the delay margin of the
box and the assumptions the verdict rests on.

Methods: ``"nuno"``, the closed form of :mod:`teleopkit.certification.nuno.condition` (nonlinear
model, frozen gains, instant); ``"lmi"``, the Lyapunov–Krasovskii LMIs of :mod:`certify` on the
linearisation at rest (:mod:`teleopkit.certification.lmi.verdict`; seconds for one joint, minutes
for two); ``"all"``, both. Gain classes: :mod:`teleopkit.certification.gain_classes`.
"""

from __future__ import annotations

from collections.abc import Callable

from teleopkit.certification.delay_bounds import check_delay_bounds, check_delay_floors
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.nuno.condition import certify_closed_form
from teleopkit.certification.nuno.scheduled import certify_scheduled
from teleopkit.model.params import TeleoperatorParams, paper_setup

__all__ = [
    "DEFAULT_BOX",
    "METHODS",
    "best_certificate",
    "certify_gains",
    "default_certificate",
    "methods_for",
]

METHODS = ("nuno", "lmi", "all")
"""Values of ``method`` accepted by :func:`certify_gains`."""

DEFAULT_BOX = ((1.0, 50.0), (1.0, 150.0))
"""Default ``(K_r, B_r)`` ranges of every joint: the action space of the environments."""

Certifier = Callable[[TeleoperatorParams, GainBox, float, float, GainVariation,
                      tuple[float, float]], GainCertificate]


def _lmi() -> Certifier:
    from teleopkit.certification.lmi.verdict import certify_lmi  # cvxpy: only when asked for

    return certify_lmi


def _closed_form(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                 variation: GainVariation, delay_lower: tuple[float, float]) -> GainCertificate:
    """The closed-form family: Nuño's condition for frozen gains, its storage for schedules.

    Both cover every delay in ``[0, T_i*]``, hence any minimum delay (``delay_lower`` is not
    needed and the certificate records 0).
    """
    certify = certify_scheduled if variation.scheduled else certify_closed_form
    return certify(params, box, tl_max, tr_max, variation)


_METHODS: dict[str, Callable[[], Certifier]] = {"nuno": lambda: _closed_form, "lmi": _lmi}


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


def certify_gains(params: TeleoperatorParams, box: GainBox, tl_max: float = 1.0,
                  tr_max: float = 1.0, method: str = "nuno",
                  variation: GainVariation | str = "frozen", tl_min: float = 0.0,
                  tr_min: float = 0.0) -> GainCertificate:
    """Certify a box of remote gains for delays ``T_l_min <= T_l(t) <= T_l*``, likewise ``T_r``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (local gains, operator, joints, arms).
    box : GainBox
        Remote gain ranges per joint.
    tl_max, tr_max : float
        Delay bounds in seconds (positive).
    method : {"nuno", "lmi", "all"}
        Certification method; ``"all"`` runs every method that covers the gain class and
        returns the best certificate (:func:`best_certificate`).
    variation : GainVariation or str
        Gain class: ``"frozen"``, ``"switching"``, ``"rate:R"``, ``"scheduled:L"`` or
        ``"tank[:T0]"`` (:mod:`teleopkit.certification.gain_classes`).
    tl_min, tr_min : float
        Minimum delays in seconds (a network's latency floor), in ``[0, T_i*)``. The LMIs use
        them (a larger certified set); the closed form covers delays from 0 whatever they are.

    Returns
    -------
    GainCertificate
        The verdict, admissible polytope and delay margin.

    Examples
    --------
    >>> from teleopkit.model.params import paper_setup
    >>> box = GainBox.uniform((5.0, 10.0), (30.0, 60.0))
    >>> cert = certify_gains(paper_setup(), box, 1.0, 1.0, method="nuno")
    >>> cert.certified, round(cert.delay_margin, 4)
    (True, 1.0954)
    """
    if isinstance(variation, str):
        variation = parse_gain_variation(variation)
    if box.n_joints != params.n_joints:
        raise ValueError(f"gain box has {box.n_joints} joints, the teleoperator {params.n_joints}")
    tl_max, tr_max = check_delay_bounds(tl_max, tr_max)
    lower = check_delay_floors(tl_min, tr_min, tl_max, tr_max)
    return best_certificate([_METHODS[name]()(params, box, tl_max, tr_max, variation, lower)
                             for name in methods_for(method, variation)])


def default_certificate(params: TeleoperatorParams | None = None, delay_bound: float = 1.0,
                        variation: GainVariation | str = "frozen") -> GainCertificate:
    """Closed-form certificate of :data:`DEFAULT_BOX` for delays up to ``delay_bound``.

    The box itself is not certified (at ``K_r = 50`` it needs ``B_r >= 125`` for 1 s delays);
    the certificate's polytope, the box cut by the closed-form half-plane of each joint, is, and
    it is what the safety layer of the environments projects onto by default.

    Parameters
    ----------
    params : TeleoperatorParams, optional
        Teleoperator; the paper's by default.
    delay_bound : float
        ``T_l* = T_r*`` in seconds.
    variation : GainVariation or str
        The gain class: ``"frozen"`` by default, or a scheduled class (``"scheduled:L"``,
        ``"tank"``), which covers what a tuner does with the gains.

    Returns
    -------
    GainCertificate
        The ``"nuno"`` certificate of the class.
    """
    params = params if params is not None else paper_setup()
    box = GainBox.uniform(*DEFAULT_BOX, n_joints=params.n_joints)
    return certify_gains(params, box, delay_bound, delay_bound, method="nuno",
                         variation=variation)
