"""Certify remote gain ranges of the teleoperator for given delay bounds.

:func:`certify_gains` answers "is every gain in this box stable for delays up to ``T_l*, T_r*``?"
with a :class:`GainCertificate`: the verdict, the admissible polytope inside the box (what the
safety layer projects onto), the delay margin of the box and the assumptions the verdict rests on.

Method: ``"nuno"``, the closed form of :mod:`teleopkit.closed_form` (nonlinear model, frozen
gains); the LMI analysis of the linearisation (package :mod:`certify`) joins it as a second method.
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

from teleopkit.closed_form import ASSUMPTIONS as NUNO_ASSUMPTIONS
from teleopkit.closed_form import nuno_delay_margin, nuno_margins, nuno_polytope
from teleopkit.gains import GainBox, GainPolytope
from teleopkit.params import TeleoperatorParams

__all__ = ["GainCertificate", "GainVariation", "certify_gains", "parse_gain_variation"]

METHODS = ("nuno",)


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
    """Parse ``frozen``, ``switching`` or ``rate:R``."""
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
        Certified gains inside the box (the safety layer's set); may be smaller than the box.
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
            "assumptions": list(self.assumptions),
            "violation": self.violation,
            "details": self.details,
        }

    def to_json(self, indent: int | None = 2) -> str:
        """JSON text of :meth:`to_dict`."""
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_json(cls, text: str) -> GainCertificate:
        """Inverse of :meth:`to_json`; raises ValueError on malformed text."""
        try:
            data = json.loads(text)
            ranges = data["box"]
            box = GainBox(tuple(map(tuple, ranges["kr"])), tuple(map(tuple, ranges["br"])))
            margin = data["delay_margin"]
            return cls(bool(data["certified"]), str(data["method"]), str(data["gain_variation"]),
                       tuple(data["delay_bounds"]), math.inf if margin == "inf" else float(margin),
                       box, GainPolytope.from_dict(data["polytope"]),
                       tuple(data["assumptions"]), data["violation"], dict(data["details"]))
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
                           nuno_polytope(params, box, tl_max, tr_max), NUNO_ASSUMPTIONS,
                           violation, {"slack": slack.tolist()})


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
    method : {"nuno"}
        Certification method.
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
    if method == "nuno":
        return _certify_nuno(params, box, tl_max, tr_max, variation)
    raise ValueError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
