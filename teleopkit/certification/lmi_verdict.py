"""The LMI answer to "is this gain box stable?": verdict, certified polytope and delay margin.

:func:`certify_lmi` certifies a box with the LMIs of :mod:`teleopkit.certification.lmi` (one
functional, or cells of :mod:`teleopkit.certification.cover` for constant gains of large sets).
When the box is not certified it names a failing vertex and offers the largest certified member
of the family of boxes cut by the closed form at ``s T*``; the delay margin of constant gains of
large sets is searched by covers between a lower bound and the limiting vertex's own margin.
"""

from __future__ import annotations

from typing import Any

from teleopkit.certification.certificate import GainCertificate
from teleopkit.certification.classes import GainVariation
from teleopkit.certification.closed_form import nuno_polytope
from teleopkit.certification.cover import cover_margin, limiting_vertex, set_certificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi import (
    LMI_METHOD,
    enumerated,
    lmi_delay_margin,
    vertex_certificate,
)
from teleopkit.model.params import TeleoperatorParams, plant_record

__all__ = ["MARGIN_BUDGET", "certify_lmi"]

MARGIN_BUDGET = 120
"""Most LMI solves per cover when :func:`certify_lmi` searches the margin of constant gains of
a large certified set (two covers at most)."""


def _lmi_violation(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                   method: str) -> str:
    """Name a gain vertex of the box the LMI cannot certify alone, if there is one."""
    n = box.n_joints
    for action in GainPolytope.from_box(box).vertices():
        if not vertex_certificate(params, action, tl_max, tr_max, method).certified:
            return (f"LMI ({method}) infeasible at the vertex K_r = {action[:n].tolist()}, "
                    f"B_r = {action[n:].tolist()} for T_l* = {tl_max:g}, T_r* = {tr_max:g}")
    return (f"LMI ({method}) infeasible for the box as a whole (every vertex is certified "
            "alone)")


def _lmi_polytope(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                  kind: str, method: str, steps: int) -> tuple[GainPolytope, bool]:
    """Largest certified polytope of the family ``box`` cut by the closed form at ``s T*``.

    ``s = 1`` is the closed-form polytope; smaller ``s`` cut less. Bisection on ``s`` over
    ``steps`` solves after the first certified member (doubling ``s`` up to three times when
    ``s = 1`` is not certified).
    """
    def member(scale: float) -> GainPolytope:
        return nuno_polytope(params, box, scale * tl_max, scale * tr_max)

    def certified(scale: float) -> bool:
        polytope = member(scale)
        return (not polytope.is_empty()
                and set_certificate(params, polytope, tl_max, tr_max, kind, method).certified)

    low, high = 0.0, 1.0
    for _ in range(3):
        if certified(high):
            break
        low, high = high, 2.0 * high
    else:
        return member(1.0), False
    for _ in range(steps):
        mid = 0.5 * (low + high)
        low, high = (low, mid) if certified(mid) else (mid, high)
    return member(high), True


def certify_lmi(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                variation: GainVariation, method: str = LMI_METHOD,
                steps: int = 3) -> GainCertificate:
    """The LMI certificate of a gain box on the linearisation at rest.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : GainVariation
        Gain class (``rate:R`` is certified as switching: held gains jump).
    method : str
        A :data:`certify.METHODS` name.
    steps : int
        Bisection steps of the certified polytope when the box is not certified.

    Returns
    -------
    GainCertificate
        Verdict, certified polytope, delay margin and the solver's data in ``details``.
    """
    if variation.scheduled:
        raise ValueError(f"the LMI method covers frozen, switching and rate:R gains, not "
                         f"{variation}; certify {variation} with the closed form (nuno)")
    kind = "frozen" if variation.kind == "frozen" else "switching"
    whole = GainPolytope.from_box(box)
    verdict = set_certificate(params, whole, tl_max, tr_max, kind, method)
    cert = verdict.certificates[-1]
    if verdict.certified:
        polytope, polytope_certified, violation = whole, True, None
    else:
        polytope, polytope_certified = _lmi_polytope(params, box, tl_max, tr_max, kind, method,
                                                     steps)
        violation = _lmi_violation(params, box, tl_max, tr_max, method)
    known = min(tl_max, tr_max) if verdict.certified else 0.0
    margin, margin_details = _lmi_margin(params, whole, kind, method, known)
    assumptions = (
        "linearisation at rest (any rest configuration), free space, the modelled operator "
        "spring and damper, no torque saturation",
        "time-varying delays 0 <= T_i(t) <= T_i*, derivative unrestricted",
        {"frozen": "constant (frozen) remote gains",
         "switching": "remote gains switching arbitrarily fast inside the set",
         "rate": f"remote gains of rate at most {variation.rate:g}/s, certified as arbitrary "
                 "switching: the gains are held over each control period, so they jump by up "
                 "to the rate times the period, and only switching covers jumps"}[variation.kind],
        *cert.assumptions,
    )
    if kind == "frozen" and not enumerated(params, whole):
        assumptions += (
            "constant gains of a large set: covered by cells, each certified for gains switching "
            "inside it; the delay margin likewise when the set is certified, else the whole "
            "set's with switching gains (a lower bound); details.margin_limit is an upper limit",)
    details = {"lmi_method": method, "solver_status": cert.status,
               "residuals": dict(cert.residuals), "vertices": len(cert.system.vertices),
               "cells": len(verdict.cells), "solves": verdict.solves, **margin_details}
    return GainCertificate(verdict.certified, "lmi", str(variation), (tl_max, tr_max), margin,
                           box, polytope, polytope_certified, assumptions, violation, details,
                           plant_record(params))


def _lmi_margin(params: TeleoperatorParams, whole: GainPolytope, kind: str, method: str,
                known: float) -> tuple[float, dict[str, Any]]:
    """Delay margin of a gain set and how it was found (cells for constant gains of large sets).

    The whole set's margin with one functional is a lower bound for constant gains beyond
    :func:`enumerated`, and so is ``known`` (a common bound already certified). The limiting
    vertex's own margin is an upper limit. A set certified at the requested bounds is searched
    between the two by covers (:func:`~teleopkit.certification.cover.cover_margin`, with a budget of
    :data:`MARGIN_BUDGET` solves per cover); a set that is not, whose cells near the limiting
    vertex would be tiny (more than 20 minutes on the paper's whole box), reports the bounds.
    """
    single = float(lmi_delay_margin(params, whole, kind, method).margin or 0.0)
    if kind != "frozen" or enumerated(params, whole):
        return single, {}
    lower = max(single, known)
    if known > 0:
        found = cover_margin(params, whole, method, attempts=2, lower=lower, budget=MARGIN_BUDGET)
        vertex, limit, margin = found.vertex, found.limit, found.margin
    else:
        (vertex, limit), margin = limiting_vertex(params, whole, method), lower
    return margin, {"margin_limit": limit, "margin_limit_vertex": list(vertex)}
