"""Certify remote gain ranges of the teleoperator for given delay bounds.

:func:`certify_gains` answers "is every gain in this box stable for delays up to ``T_l*, T_r*``?"
with a :class:`GainCertificate`: the verdict, the admissible polytope inside the box (what the
safety layer projects onto), the delay margin of the box and the assumptions the verdict rests on.

Methods: ``"nuno"``, the closed form of :mod:`teleopkit.closed_form` (nonlinear model, frozen
gains, instant); ``"lmi"``, the Lyapunov–Krasovskii LMIs of :mod:`certify` on the linearisation at
rest (:mod:`teleopkit.lmi_bridge`; seconds for one joint, minutes for two); ``"all"``, both.
Gain classes: ``"frozen"`` (every constant gain in the set),
``"switching"`` (gains changing arbitrarily fast inside the set) and ``"rate:R"`` (gains whose rate
is at most ``R`` per second).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from certify import PolytopicDelaySystem, certify_delay
from teleopkit.closed_form import ASSUMPTIONS as NUNO_ASSUMPTIONS
from teleopkit.closed_form import nuno_delay_margin, nuno_margins, nuno_polytope
from teleopkit.gains import GainBox, GainPolytope
from teleopkit.linearize import rest_systems
from teleopkit.lmi_bridge import LMI_METHOD, enumerated, lmi_delay_margin
from teleopkit.lmi_cover import cover_margin, limiting_vertex, set_certificate
from teleopkit.params import TeleoperatorParams

__all__ = [
    "MARGIN_BUDGET",
    "GainCertificate",
    "GainVariation",
    "best_certificate",
    "certify_gains",
    "methods_for",
    "parse_gain_variation",
]

METHODS = ("nuno", "lmi", "all")
"""Values of ``method`` accepted by :func:`certify_gains`."""


@dataclass(frozen=True)
class GainVariation:
    """How the remote gains may vary inside the certified set.

    Parameters
    ----------
    kind : {"frozen", "switching", "rate"}
        Constant gains, arbitrarily fast changes, or changes of bounded rate.
    rate : float
        Largest rate of change (gain units per second) for ``kind="rate"``.
    """

    kind: str = "frozen"
    rate: float = math.inf

    def __post_init__(self) -> None:
        if self.kind not in ("frozen", "switching", "rate"):
            raise ValueError(f"gain variation must be frozen, switching or rate:R, got "
                             f"{self.kind!r}")
        if self.kind == "rate" and not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"gain rate bound must be positive and finite, got {self.rate}")

    def __str__(self) -> str:
        return f"rate:{self.rate:g}" if self.kind == "rate" else self.kind


def parse_gain_variation(text: str) -> GainVariation:
    """Parse ``frozen``, ``switching`` or ``rate:R``.

    Parameters
    ----------
    text : str
        The gain class: ``frozen``, ``switching`` or ``rate:R`` with ``R`` the largest rate of
        change in gain units per second.

    Returns
    -------
    GainVariation
        The parsed gain class; raises ValueError on anything else.
    """
    kind, _, rate = text.partition(":")
    if kind == "rate":
        try:
            return GainVariation("rate", float(rate))
        except ValueError:
            raise ValueError(f"gain variation rate:R needs a number, got {text!r}") from None
    if rate:
        raise ValueError(f"gain variation must be frozen, switching or rate:R, got {text!r}")
    return GainVariation(kind)


@dataclass(frozen=True)
class GainCertificate:
    """Verdict on a gain box for given delay bounds.

    Parameters
    ----------
    certified : bool
        Whether every gain of the box (varying as ``gain_variation`` says) is certified stable.
    method : str
        Certification method (``"nuno"``).
    gain_variation : str
        ``"frozen"``, ``"switching"`` or ``"rate:R"``.
    delay_bounds : tuple of float
        ``(T_l*, T_r*)``.
    delay_margin : float
        Largest common bound ``T* = T_l* = T_r*`` for which the whole box is certified.
    box : GainBox
        The box asked about.
    polytope : GainPolytope
        Gains inside the box offered to the safety layer; may be smaller than the box.
    polytope_certified : bool
        Whether ``polytope`` itself is certified (it can be when the box is not).
    assumptions : tuple of str
        What the verdict rests on.
    violation : str or None
        When not certified: the violating vertex and condition.
    details : dict
        Method-specific data (for the LMI, the solver's certificate as JSON-ready data).
    """

    certified: bool
    method: str
    gain_variation: str
    delay_bounds: tuple[float, float]
    delay_margin: float
    box: GainBox
    polytope: GainPolytope
    polytope_certified: bool
    assumptions: tuple[str, ...]
    violation: str | None = None
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (what ``teleopkit certify --json`` prints)."""
        n = self.box.n_joints
        return {
            "certified": self.certified,
            "method": self.method,
            "gain_variation": self.gain_variation,
            "delay_bounds": list(self.delay_bounds),
            "delay_margin": _json_float(self.delay_margin),
            "box": self.box.to_dict(),
            "polytope": {**self.polytope.to_dict(),
                         "joint_vertices": [self.polytope.joint_vertices(i).tolist()
                                            for i in range(n)]},
            "polytope_certified": self.polytope_certified,
            "assumptions": list(self.assumptions),
            "violation": self.violation,
            "details": self.details,
        }

    def to_json(self, indent: int | None = 2) -> str:
        """JSON text of :meth:`to_dict`.

        Parameters
        ----------
        indent : int or None
            Indentation passed to :func:`json.dumps`; None for a single line.

        Returns
        -------
        str
            The certificate as JSON (an infinite delay margin as the string ``"inf"``).
        """
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_json(cls, text: str) -> GainCertificate:
        """Inverse of :meth:`to_json`; raises ValueError on malformed text.

        Parameters
        ----------
        text : str
            JSON text as :meth:`to_json` writes it.

        Returns
        -------
        GainCertificate
            The certificate.
        """
        try:
            data = json.loads(text)
            ranges = data["box"]
            box = GainBox(tuple(map(tuple, ranges["kr"])), tuple(map(tuple, ranges["br"])))
            margin = data["delay_margin"]
            return cls(bool(data["certified"]), str(data["method"]), str(data["gain_variation"]),
                       tuple(data["delay_bounds"]), math.inf if margin == "inf" else float(margin),
                       box, GainPolytope.from_dict(data["polytope"]),
                       bool(data["polytope_certified"]), tuple(data["assumptions"]),
                       data["violation"], dict(data["details"]))
        except (KeyError, TypeError, ValueError, json.JSONDecodeError) as error:
            raise ValueError(f"malformed gain certificate: {error}") from None


def _json_float(value: float) -> float | str:
    return "inf" if value == math.inf else value


def _certify_nuno(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                  variation: GainVariation) -> GainCertificate:
    if variation.kind != "frozen":
        raise ValueError("the closed form (nuno) covers frozen gains only, not "
                         f"{variation} gains")
    worst = np.concatenate([box.upper[:box.n_joints], box.lower[box.n_joints:]])
    slack = nuno_margins(params, worst, tl_max, tr_max)
    certified = bool(np.all(slack > 0))
    violation = None
    if not certified:
        i = int(np.argmin(slack))
        violation = (f"joint {i + 1} at K_r = {worst[i]:g}, B_r = {worst[box.n_joints + i]:g}: "
                     f"4 B_l B_r - (T_l*+T_r*)^2 K_l K_r = {slack[i]:.6g} <= 0")
    return GainCertificate(certified, "nuno", str(variation), (tl_max, tr_max),
                           nuno_delay_margin(params, box), box,
                           nuno_polytope(params, box, tl_max, tr_max), True, NUNO_ASSUMPTIONS,
                           violation, {"slack": slack.tolist()})


def _lmi_violation(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                   method: str) -> str:
    """Name a gain vertex of the box the LMI cannot certify alone, if there is one."""
    n = box.n_joints
    for action in GainPolytope.from_box(box).vertices():  # one constant gain, every configuration
        point = PolytopicDelaySystem(tuple(rest_systems(params, action)), "frozen")
        if not certify_delay(point, [tl_max, tr_max], method).certified:
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


MARGIN_BUDGET = 120
"""Most LMI solves per cover when :func:`certify_gains` searches the margin of constant gains of
a large certified set (two covers at most)."""


def _certify_lmi(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                 variation: GainVariation, method: str = LMI_METHOD,
                 steps: int = 3) -> GainCertificate:
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
                           box, polytope, polytope_certified, assumptions, violation, details)


def _lmi_margin(params: TeleoperatorParams, whole: GainPolytope, kind: str, method: str,
                known: float) -> tuple[float, dict[str, Any]]:
    """Delay margin of a gain set and how it was found (cells for constant gains of large sets).

    The whole set's margin with one functional is a lower bound for constant gains beyond
    :func:`enumerated`, and so is ``known`` (a common bound already certified). The limiting
    vertex's own margin is an upper limit. A set certified at the requested bounds is searched
    between the two by covers (:func:`~teleopkit.lmi_cover.cover_margin`, with a budget of
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


def methods_for(method: str, variation: GainVariation) -> tuple[str, ...]:
    """The single methods that ``method`` runs for a gain class (``"all"`` expands).

    Parameters
    ----------
    method : {"nuno", "lmi", "all"}
        Requested method.
    variation : GainVariation
        Gain class; the closed form covers frozen gains only.

    Returns
    -------
    tuple of str
        Method names.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
    if method != "all":
        return (method,)
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
                  variation: GainVariation | str = "frozen") -> GainCertificate:
    """Certify a box of remote gains for delays ``0 <= T_l(t) <= T_l*``, ``0 <= T_r(t) <= T_r*``.

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
        Gain class: ``"frozen"``, ``"switching"`` or ``"rate:R"``.

    Returns
    -------
    GainCertificate
        The verdict, admissible polytope and delay margin.

    Examples
    --------
    >>> from teleopkit.params import paper_setup
    >>> box = GainBox.uniform((5.0, 10.0), (30.0, 60.0))
    >>> cert = certify_gains(paper_setup(), box, 1.0, 1.0, method="nuno")
    >>> cert.certified, round(cert.delay_margin, 4)
    (True, 1.0954)
    """
    if isinstance(variation, str):
        variation = parse_gain_variation(variation)
    if box.n_joints != params.n_joints:
        raise ValueError(f"gain box has {box.n_joints} joints, the teleoperator {params.n_joints}")
    for name, value in (("T_l*", tl_max), ("T_r*", tr_max)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"delay bound {name} must be positive and finite, got {value}")
    run = {"nuno": _certify_nuno, "lmi": _certify_lmi}
    return best_certificate([run[name](params, box, tl_max, tr_max, variation)
                             for name in methods_for(method, variation)])
