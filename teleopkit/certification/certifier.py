"""Certify remote gain ranges of the teleoperator for given delay bounds.

:func:`certify_gains` answers "is every gain in this box stable for delays up to ``T_l*, T_r*``?"
with a :class:`~teleopkit.certification.gain_certificate.GainCertificate`: the verdict, the
admissible polytope inside the box (what the safety layer projects onto), the delay margin of the
box and the assumptions the verdict rests on.

Methods are in :mod:`teleopkit.certification.methods`, gain classes in
:mod:`teleopkit.certification.gain_classes`. The LMI method solves on worker processes
(``workers=``, :mod:`teleopkit.certification.lmi.workers`) and, asked to, keeps its answers on
disk (``cache=True``, :mod:`teleopkit.certification.cache`), re-verified whenever they are
reused.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

from teleopkit.certification.cache import cached
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.lmi.workers import start_workers, using_workers
from teleopkit.certification.methods import best_certificate, certify_with, methods_for
from teleopkit.certification.nuno.guarantee import Start
from teleopkit.certification.nuno.scheduled import plants_tank
from teleopkit.certification.question import Question
from teleopkit.certification.verification import cover_plants
from teleopkit.model.params import TeleoperatorParams, paper_setup
from teleopkit.model.plant_range import PlantRange
from teleopkit.progress import reports_progress

__all__ = ["DEFAULT_BOX", "certify_all", "certify_gains", "default_certificate"]

DEFAULT_BOX = ((1.0, 50.0), (1.0, 150.0))
"""Default ``(K_r, B_r)`` ranges of every joint: the action space of the environments."""

_log = logging.getLogger("teleopkit.certification")


@reports_progress
def certify_all(params: TeleoperatorParams, box: GainBox, tl_max: float = 1.0,
                tr_max: float = 1.0, method: str = "nuno",
                variation: GainVariation | str = "frozen", tl_min: float = 0.0,
                tr_min: float = 0.0, workers: int | None = None, cache: bool = False,
                on_proven: Callable[[GainCertificate], None] | None = None,
                progress: bool | None = None) -> list[GainCertificate]:
    """The answer of every method that ``method`` runs for the class (see :func:`certify_gains`).

    Parameters
    ----------
    params, box, tl_max, tr_max, method, variation, tl_min, tr_min, workers, cache, progress
        As in :func:`certify_gains`.
    on_proven : callable, optional
        Handed each larger set the LMI method proves on the way (a certificate whose margin was
        not searched), for example to show progress or keep the best set of an interrupted run.

    Returns
    -------
    list of GainCertificate
        One certificate per method, in the order of
        :func:`~teleopkit.certification.methods.methods_for`.
    """
    question = Question(params, box, (tl_max, tr_max), (tl_min, tr_min), variation)

    def answer(name: str) -> GainCertificate:
        def compute() -> GainCertificate:
            if name == "lmi":  # the workers start while the LMI modules are imported here
                start_workers()
            return certify_with(name, question, on_proven)

        if name != "lmi" or not cache:  # the closed form is instant
            return compute()
        certificate, reused = cached(question.key(name), compute)
        if reused:
            _log.info("LMI certificate reused from the cache (re-verified)")
        return certificate

    with using_workers(workers):
        return [answer(name) for name in methods_for(method, question.gain_class)]


def certify_gains(params: TeleoperatorParams, box: GainBox, tl_max: float = 1.0,
                  tr_max: float = 1.0, method: str = "nuno",
                  variation: GainVariation | str = "frozen", tl_min: float = 0.0,
                  tr_min: float = 0.0, workers: int | None = None,
                  cache: bool = False, progress: bool | None = None) -> GainCertificate:
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
    workers : int, optional
        Worker processes of the LMI solves (1: in this process); default
        ``TELEOPKIT_WORKERS``, else the core count.
    cache : bool
        Reuse an LMI certificate of the same question kept on disk (re-verified against the
        plant) and keep new ones there (:mod:`teleopkit.certification.cache`).
    progress : bool, optional
        Show the LMI search (cells solved, margin bracket) on standard error: by default on a
        terminal only; ``False`` never, ``True`` always (:mod:`teleopkit.progress`).

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
    return best_certificate(certify_all(params, box, tl_max, tr_max, method, variation, tl_min,
                                        tr_min, workers, cache, progress=progress))


def default_certificate(params: TeleoperatorParams | None = None,
                        delay_bound: float | tuple[float, float] = 1.0,
                        variation: GainVariation | str = "frozen",
                        plants: Sequence[TeleoperatorParams] = (),
                        ranges: Sequence[PlantRange] = (), start: Start | None = None,
                        ) -> GainCertificate:
    """Closed-form certificate of :data:`DEFAULT_BOX` for delays up to ``delay_bound``.

    The box itself is not certified (at ``K_r = 50`` it needs ``B_r >= 125`` for 1 s delays);
    the certificate's polytope, the box cut by the closed-form half-plane of each joint, is, and
    it is what the safety layer of the environments projects onto by default.

    Parameters
    ----------
    params : TeleoperatorParams, optional
        Teleoperator; the paper's by default.
    delay_bound : float or (float, float)
        ``T_l* = T_r*`` in seconds, or the pair ``(T_l*, T_r*)``.
    variation : GainVariation or str
        The gain class: ``"frozen"`` by default, or a scheduled class (``"scheduled:L"``,
        ``"tank"``), which covers what a tuner does with the gains.
    plants : sequence of TeleoperatorParams, optional
        Further plants to cover (a setup's :attr:`~teleopkit.setup.Setup.plants`):
        :func:`~teleopkit.certification.verification.cover_plants`.
    ranges : sequence of PlantRange, optional
        The range of each of ``plants`` (a setup's :attr:`~teleopkit.setup.Setup.ranges`).
    start : StartSpec or StartMix, optional
        Initial positions (the ``start`` of a :class:`~teleopkit.setup.Setup`) a tank asked for in
        ``rad`` is sized from; ``params.initial`` by default.

    Returns
    -------
    GainCertificate
        The ``"nuno"`` certificate of the class.
    """
    params = params if params is not None else paper_setup()
    box = GainBox.uniform(*DEFAULT_BOX, n_joints=params.n_joints)
    forward, backward = (delay_bound if isinstance(delay_bound, tuple)
                         else (delay_bound, delay_bound))
    variation = plants_tank(plants or [params], box, forward, backward, variation, ranges, start)
    certificate = certify_gains(params, box, forward, backward, method="nuno",
                                variation=variation)
    return cover_plants(certificate, plants, ranges) if plants else certificate
