"""The LMI answer to "is this gain box stable?": verdict, certified polytope and delay margin.

:func:`certify_lmi` certifies a box with the LMIs of :mod:`teleopkit.certification.lmi.systems` (one
functional, or cells of :mod:`teleopkit.certification.lmi.cover` for constant gains of large sets).
When the box is not certified it names a failing vertex and offers the largest certified member
of the family of boxes cut by the closed form at ``s T*``; the delay margin of constant gains of
large sets is searched by covers between a lower bound and the limiting vertex's own margin.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.gain_classes import parse_gain_variation as parse_variation
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.cells import CellMemo
from teleopkit.certification.lmi.cover import (
    LIMIT_RTOL,
    Cover,
    cover_margin,
    limiting_vertex,
    set_certificate,
)
from teleopkit.certification.lmi.proof import certificate_proof, check_proof, cover_proof
from teleopkit.certification.lmi.systems import (
    LMI_METHOD,
    NO_LOWER,
    DelayQuestion,
    enumerated,
    lmi_certificate,
    lmi_delay_margin,
)
from teleopkit.certification.lmi.workers import Background, map_solves, start_workers
from teleopkit.certification.nuno.condition import nuno_polytope, weakest_first
from teleopkit.certification.question import Question
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.records import plant_params, plant_record

__all__ = [
    "MARGIN_BUDGET",
    "MARGIN_FLOOR",
    "PARTIAL",
    "certify_lmi",
    "check_lmi",
    "cut_polytope",
    "lmi_assumptions",
]

_log = logging.getLogger(__name__)

MARGIN_FLOOR = 1e-3
"""Delay margins (above the minimum delays) below this, in seconds, are not searched: 0."""

PARTIAL = ("proven at the requested delay bounds; the delay margin was not searched (an "
           "interrupted certification keeps this)")
"""``details["partial"]`` of the certificates :func:`certify_lmi` hands its ``on_proven``."""

MARGIN_BUDGET = 120
"""Most LMI solves per cover when :func:`certify_lmi` searches the margin of constant gains of
a large certified set (two covers at most)."""


def _lmi_violation(params: TeleoperatorParams, box: GainBox, memo: CellMemo) -> str:
    """Name a gain vertex of the box the LMI cannot certify alone, if there is one."""
    n = box.n_joints
    (tl_max, tr_max), method = memo.question.bounds, memo.question.method
    corners = GainPolytope.from_box(box).vertices()
    for action in corners[weakest_first(params, corners)]:
        cert = memo.vertex(action)
        if cert is None:
            cert = memo.question.vertex(action)
            memo.record_vertex(action, cert)
        if not cert.certified:
            return (f"LMI ({method}) infeasible at the vertex K_r = {action[:n].tolist()}, "
                    f"B_r = {action[n:].tolist()} for T_l* = {tl_max:g}, T_r* = {tr_max:g}")
    return (f"LMI ({method}) infeasible for the box as a whole (every vertex is certified "
            "alone)")


def cut_polytope(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                 scale: float) -> GainPolytope:
    """A member of the family of :func:`certify_lmi`: the box cut by the closed form at ``s T*``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    scale : float
        The factor ``s`` (1: the closed-form polytope; smaller cuts less).

    Returns
    -------
    GainPolytope
        The member.
    """
    return nuno_polytope(params, box, scale * tl_max, scale * tr_max)


def _lmi_polytope(params: TeleoperatorParams, box: GainBox, kind: str, steps: int,
                  memo: CellMemo, proven: Callable[[float, Cover], None]
                  ) -> tuple[float, Cover | None]:
    """Largest certified member of the family :func:`cut_polytope`, by its scale ``s``.

    Bisection on ``s`` over ``steps`` solves after the first certified member (doubling ``s``
    up to three times when ``s = 1`` is not certified); the members are nested, so their covers
    share the verdicts of ``memo``. Each member certified larger than the last is handed to
    ``proven``. Returns ``s`` and the member's cover (``s = 1`` and ``None`` if no member was
    certified).
    """
    tl_max, tr_max = memo.question.bounds
    root = (box.lower, box.upper)  # every member is split from the box: their cells line up
    covers: dict[float, Cover] = {}

    def certified(scale: float) -> bool:
        _log.info("largest certified cut: trying s = %.4g (certified: %s)", scale,
                  max((s for s, c in covers.items() if c.certified), default="none"))
        polytope = cut_polytope(params, box, tl_max, tr_max, scale)
        if polytope.is_empty():
            return False
        covers[scale] = set_certificate(memo.question, polytope, kind, memo=memo, root=root)
        if covers[scale].certified:
            proven(scale, covers[scale])
        return covers[scale].certified

    low, high = 0.0, 1.0
    for _ in range(3):
        if certified(high):
            break
        low, high = high, 2.0 * high
    else:
        return 1.0, None
    for _ in range(steps):
        mid = 0.5 * (low + high)
        low, high = (low, mid) if certified(mid) else (mid, high)
    return high, covers[high]


def certify_lmi(question: Question, method: str = LMI_METHOD, steps: int = 3,
                on_proven: Callable[[GainCertificate], None] | None = None) -> GainCertificate:
    """The LMI certificate of a question's gain box on the linearisation at rest.

    Parameters
    ----------
    question : Question
        Plant, gain box, delay bounds and minimum delays (the delays lie in
        ``[T_i_min, T_i*]``) and gain class (``rate:R`` is certified as switching: held gains
        jump).
    method : str
        A :data:`certify.METHODS` name (the LMI formulation).
    steps : int
        Bisection steps of the certified polytope when the box is not certified.
    on_proven : callable, optional
        Called with a certificate each time a larger set is proven at the requested bounds (the
        whole box, or a larger member of the cut family), before the delay margin is searched:
        a complete certificate of that set with its margin not searched (0), marked so in
        ``details["partial"]``. What an interrupted certification keeps.

    Returns
    -------
    GainCertificate
        Verdict, certified polytope, delay margin and the solver's data in ``details``.
    """
    params, box, variation = question.params, question.box, question.gain_class
    (tl_max, tr_max), delay_lower = question.bounds, question.lower
    if variation.scheduled:
        raise ValueError(f"the LMI method covers frozen, switching and rate:R gains, not "
                         f"{variation}; certify {variation} with the closed form (nuno)")
    kind = "frozen" if variation.kind == "frozen" else "switching"
    bounds = (tl_max, tr_max)
    whole = GainPolytope.from_box(box)
    start_workers()  # while the first solves run here
    limit = (Background(limiting_vertex, params, whole, method, delay_lower)  # beside the covers
             if kind == "frozen" and not enumerated(params, whole) else None)
    memo = CellMemo(DelayQuestion(params, bounds, delay_lower, method))  # shared by the covers
    verdict = set_certificate(memo.question, whole, kind, memo=memo, root=(box.lower, box.upper))
    cert = verdict.certificates[-1]
    proof_details: dict[str, Any] = {}

    def proven(polytope: GainPolytope, certified: bool, extra: dict[str, Any]) -> None:
        if on_proven is None:
            return
        on_proven(GainCertificate(
            certified, "lmi", str(variation), bounds, 0.0, box, polytope, True,
            lmi_assumptions(variation, delay_lower),
            None if certified else "a member of the cut family is certified; the box was not",
            {"lmi_method": method, **extra, "partial": PARTIAL}, plant_record(params),
            delay_lower))

    if verdict.certified:
        polytope, polytope_certified, violation = whole, True, None
        proof_details["proof"] = cover_proof(verdict, bounds, delay_lower)
        proven(whole, True, proof_details)
    else:
        scale, cover = _lmi_polytope(params, box, kind, steps, memo, lambda s, c: proven(
            cut_polytope(params, box, tl_max, tr_max, s), False,
            {"polytope_scale": s, "proof": cover_proof(c, bounds, delay_lower)}))
        polytope = cut_polytope(params, box, tl_max, tr_max, scale)
        polytope_certified = cover is not None
        proof_details["polytope_scale"] = scale
        if cover is not None:
            proof_details["proof"] = cover_proof(cover, bounds, delay_lower)
        violation = _lmi_violation(params, box, memo)
    known = min(bounds) if verdict.certified else 0.0
    margin, margin_details = _lmi_margin(params, whole, kind, method, known,
                                         proof_details.get("proof"), delay_lower, limit)
    details = {"lmi_method": method, "solver_status": cert.status,
               "residuals": dict(cert.residuals), "vertices": len(cert.system.vertices),
               "cells": len(verdict.cells), "solves": verdict.solves,
               "how": _how(params, whole, kind, verdict),
               "lmi_assumptions": list(cert.assumptions), **margin_details, **proof_details}
    return GainCertificate(verdict.certified, "lmi", str(variation), bounds, margin, box,
                           polytope, polytope_certified, lmi_assumptions(variation, delay_lower),
                           violation, details, plant_record(params), delay_lower)


def lmi_assumptions(variation: GainVariation, delay_lower: tuple[float, float] = NO_LOWER
                    ) -> tuple[str, ...]:
    """What an LMI certificate of a gain class covers, in the user's words.

    Parameters
    ----------
    variation : GainVariation
        The gain class certified.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)``.

    Returns
    -------
    tuple of str
        The assumptions (how the proof was built is in the certificate's ``details``).
    """
    floor = ("0" if not any(delay_lower) else
             f"T_i_min (T_l_min = {delay_lower[0]:g} s, T_r_min = {delay_lower[1]:g} s)")
    return (
        "the linearisation at rest (any rest configuration, configuration frozen), free space, "
        "the modelled operator spring and damper, no torque saturation",
        f"time-varying delays {floor} <= T_i(t) <= T_i*, derivative unrestricted",
        {"frozen": "constant (frozen) remote gains: every gain of the set, each held for the "
                   "whole run",
         "switching": "remote gains switching arbitrarily fast inside the set",
         "rate": f"remote gains of rate at most {variation.rate:g}/s, certified as arbitrary "
                 "switching: the gains are held over each control period, so they jump by up "
                 "to the rate times the period, and only switching covers jumps"}[variation.kind],
    )


def _how(params: TeleoperatorParams, whole: GainPolytope, kind: str, verdict: Cover) -> str:
    """How the verdict was proven, for the certificate's details."""
    if kind == "frozen" and not enumerated(params, whole):
        return (f"constant gains of a large set: covered by {len(verdict.cells)} cells, each "
                "certified for gains switching inside it (one functional per cell, gains as "
                "multiplier uncertainties); the margin likewise, margin_limit an upper limit")
    if kind == "frozen":
        return ("one functional per gain vertex and rest configuration (enumerated), which "
                "covers each constant gain of the set")
    return ("one functional for the whole set, gains as multiplier uncertainties, which covers "
            "gains switching arbitrarily fast")


def _lmi_margin(params: TeleoperatorParams, whole: GainPolytope, kind: str, method: str,
                known: float, known_proof: dict[str, Any] | None,
                delay_lower: tuple[float, float],
                limiting: Background[tuple[tuple[float, ...], float]] | None = None
                ) -> tuple[float, dict[str, Any]]:
    """Delay margin of a gain set and how it was found (cells for constant gains of large sets).

    The whole set's margin with one functional is a lower bound for constant gains beyond
    :func:`enumerated`, and so is ``known`` (a common bound already certified). The limiting
    vertex's own margin is an upper limit. A set certified at the requested bounds is searched
    between the two by covers (:func:`~teleopkit.certification.lmi.cover.cover_margin`, with a
    budget of :data:`MARGIN_BUDGET` solves per cover); a set that is not, whose cells near the
    limiting vertex would be tiny (more than 20 minutes on the paper's whole box), reports the
    bounds. Without a cover, the one-functional margin is bisected below the limit, unless both
    ends fail (:func:`_fails_at_both_ends`). ``limiting`` is the limiting vertex's search if it
    was started earlier.
    """
    def single(h_max: float = 100.0) -> tuple[float, dict[str, Any] | None]:
        if h_max <= max(delay_lower) + MARGIN_FLOOR:
            return 0.0, None
        found = lmi_delay_margin(params, whole, kind, method, delay_lower=delay_lower,
                                 h_max=h_max, h_min=MARGIN_FLOOR)
        margin = float(found.margin or 0.0)
        return margin, certificate_proof(found, kind) if margin > 0 else None

    if kind != "frozen" or enumerated(params, whole):
        margin, proof = single()
        return margin, {"margin_proof": proof}
    (vertex, limit) = (limiting.result() if limiting is not None
                       else limiting_vertex(params, whole, method, delay_lower))
    found = (cover_margin(params, whole, method, attempts=2, known=known, budget=MARGIN_BUDGET,
                          limit=(vertex, limit), delay_lower=delay_lower)
             if known > 0 else None)
    if found is not None and found.cover is not None:
        margin = found.margin
        proof = cover_proof(found.cover, (margin, margin), delay_lower)
    else:  # no cover above what is known: the one-functional margin, or the requested bounds
        h_max = limit / (1.0 - LIMIT_RTOL)  # the limit is to LIMIT_RTOL
        nothing = h_max <= max(delay_lower) + MARGIN_FLOOR or _fails_at_both_ends(
            params, whole, kind, method, delay_lower, h_max)
        margin, proof = (0.0, None) if nothing else single(h_max)
        if known >= margin:
            margin, proof = known, known_proof
    return margin, {"margin_limit": limit, "margin_limit_vertex": list(vertex),
                    "margin_proof": proof}


def _fails_at_both_ends(params: TeleoperatorParams, whole: GainPolytope, kind: str,
                        method: str, delay_lower: tuple[float, float], h_max: float) -> bool:
    """Whether one functional for the whole set fails at ``h_max`` and :data:`MARGIN_FLOOR`.

    The two bounds are solved side by side; if both fail, the set's margin with one functional
    is 0 (a certificate at a bound covers every smaller one) and no bisection is needed.
    """
    bounds = (h_max, max(delay_lower) + MARGIN_FLOOR)
    certs = map_solves(lmi_certificate, [(params, whole, h, h, kind, method, delay_lower)
                                         for h in bounds], share_cores=True)
    return not any(cert.certified for cert in certs)


def check_lmi(certificate: GainCertificate) -> None:
    """Raise unless an LMI certificate's proofs hold for the plant and box it records.

    The offered polytope must be the box (when the box is certified) or the member of
    :func:`cut_polytope` at the recorded scale; a certified polytope needs a proof that holds
    (:func:`~teleopkit.certification.lmi.proof.check_proof`), and so does a positive delay margin.

    Parameters
    ----------
    certificate : GainCertificate
        An LMI certificate (``method == "lmi"``).

    Raises
    ------
    ValueError
        One line naming what does not check out.
    """
    params = plant_params(certificate.plant)
    details = certificate.details
    tl_max, tr_max = certificate.delay_bounds
    variation = parse_variation(certificate.gain_variation)
    if certificate.assumptions != lmi_assumptions(variation, certificate.delay_lower):
        raise ValueError("the certificate's assumptions are not those of its gain class and "
                         "delay bounds (edited?)")
    covering = ("frozen", "switching") if variation.kind == "frozen" else ("switching",)
    whole = GainPolytope.from_box(certificate.box)
    expected = (whole if certificate.certified else
                cut_polytope(params, certificate.box, tl_max, tr_max,
                             float(details.get("polytope_scale", 1.0))))
    if not expected.same_as(certificate.polytope):
        raise ValueError("the certificate's gain polytope is not the one its plant, box and "
                         "delay bounds give (edited?)")
    if certificate.polytope_certified or certificate.certified:
        if "proof" not in details:
            raise ValueError("the certificate claims a certified set but carries no LMI proof")
        check_proof(params, certificate.polytope, details["proof"], (tl_max, tr_max), covering,
                     certificate.delay_lower)
    if certificate.delay_margin > 0:
        proof = details.get("margin_proof")
        if proof is None:
            raise ValueError("the certificate states a delay margin but carries no LMI proof of it")
        margin = certificate.delay_margin
        check_proof(params, whole, proof, (margin, margin), covering, certificate.delay_lower)
