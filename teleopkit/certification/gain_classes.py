"""Gain classes: how the remote gains may vary inside a certified set.

=================  ================================================================================
class              what the remote gains may do
=================  ================================================================================
``frozen``         stay constant (every constant gain of the set is certified)
``switching``      change arbitrarily fast inside the set
``rate:R``         change by at most ``R`` gain units per second (certified as switching: the plant
                   holds each gain over a control period, so held gains still jump)
``scheduled:L``    the proportional gains share the local gains' shape,
                   ``K_r(t) = kappa(t) K_l / K_l^1``; ``kappa`` may rise freely and fall by a total
                   log-ratio ``sum ln(kappa_- / kappa_+) <= L`` per episode; the damping gains
                   switch freely inside the cone ``B_r^i >= rho_i K_r^i``
``tank[:T0]``      as ``scheduled``, with every fall of ``kappa`` paid from an energy tank that
                   starts at ``T0`` and is refilled by the dissipation the storage proves (needs
                   the remote arm's stored energy to be measured); ``tank:0.5rad`` asks for the
                   tank whose bound allows 0.5 rad of spring deflection from the start
=================  ================================================================================

The two last classes are proven on the nonlinear teleoperator by one Lyapunov–Krasovskii storage
(:mod:`teleopkit.certification.nuno.lyapunov`); the safety layer enforces them at every control
step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["KINDS", "GainVariation", "parse_gain_variation"]

KINDS = ("frozen", "switching", "rate", "scheduled", "tank")
"""The gain classes."""

_SYNTAX = "frozen, switching, rate:R, scheduled:L or tank[:T0 or :Drad]"

_DESCRIPTIONS = {
    "frozen": "constant remote gains: each gain of the set, held for the whole run",
    "switching": "remote gains switching arbitrarily fast inside the set",
    "rate": "remote gains changing by at most {value:g} per second (certified as switching)",
    "scheduled": ("remote stiffness of the local gains' shape, rising freely and falling by a log "
                  "budget of {value:g} per episode; damping switching freely in the cone "
                  "B_r >= rho K_r"),
    "tank": ("remote stiffness of the local gains' shape, falls paid from an energy tank (initial "
             "level {value:g}{unit}) refilled by the proven dissipation; damping switching freely "
             "in the cone B_r >= rho K_r"),
}


@dataclass(frozen=True)
class GainVariation:
    """How the remote gains may vary inside the certified set.

    Parameters
    ----------
    kind : {"frozen", "switching", "rate", "scheduled", "tank"}
        The class (see the module docstring).
    value : float
        The class's number: the rate bound ``R`` (gain units per second) for ``rate``, the log
        budget ``L`` for ``scheduled``, the initial tank level ``T0`` for ``tank`` (in storage
        units, rad^2); unused otherwise.
    unit : {"", "rad"}
        ``"rad"``: a tank given by the spring deflection its bound allows (``value`` in rad),
        turned into ``T0`` when a plant is certified
        (:func:`~teleopkit.certification.nuno.guarantee.resolve_tank`).
    """

    kind: str = "frozen"
    value: float = math.nan
    unit: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"gain variation must be {_SYNTAX}, got {self.kind!r}")
        value = float(self.value)
        if self.kind == "rate" and not (math.isfinite(value) and value > 0):
            raise ValueError(f"gain variation rate:R needs a positive finite rate, got {value:g}")
        if self.kind == "scheduled" and not (math.isfinite(value) and value >= 0):
            raise ValueError(f"gain variation scheduled:L needs a finite log budget L >= 0, "
                             f"got {value:g}")
        if self.unit not in ("", "rad") or (self.unit and self.kind != "tank"):
            raise ValueError(f"only a tank takes a unit (tank:0.5rad), got {self.kind} with "
                             f"{self.unit!r}")
        if self.kind == "tank":
            if self.unit == "rad" and not (math.isfinite(value) and value > 0):
                raise ValueError(f"gain variation tank:Drad needs a positive finite deflection, "
                                 f"got {value:g} rad")
            value = 0.0 if math.isnan(value) else value  # no number: an empty tank
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"gain variation tank:T0 needs a finite initial level T0 >= 0, "
                                 f"got {value:g}")
        object.__setattr__(self, "value", value)

    @property
    def rate(self) -> float:
        """The rate bound of a ``rate:R`` class (``inf`` for every other class)."""
        return self.value if self.kind == "rate" else math.inf

    @property
    def scheduled(self) -> bool:
        """Whether the class is enforced with run-time state (``scheduled`` and ``tank``)."""
        return self.kind in ("scheduled", "tank")

    @property
    def covers_changes(self) -> bool:
        """Whether gains may change from one control period to the next."""
        return self.kind != "frozen"

    def covers(self, other: GainVariation) -> bool:
        """Whether every schedule of the class ``other`` is a schedule of this class.

        ``switching`` covers ``frozen``, every ``rate:R`` and itself; ``rate:R`` covers
        ``frozen`` and ``rate:R'`` for ``R' <= R``; ``scheduled:L`` covers ``scheduled:L'`` for
        ``L' <= L``; ``tank:T0`` covers ``tank:T0'`` for ``T0' <= T0``; every class covers itself.

        Parameters
        ----------
        other : GainVariation
            The class to be covered (for example the one a tuner was trained under).

        Returns
        -------
        bool
            Whether it is covered.
        """
        if self.kind == "switching":
            return other.kind in ("frozen", "rate", "switching")
        if self.kind == "rate":
            return other.kind == "frozen" or (other.kind == "rate" and other.value <= self.value)
        if self.kind in ("scheduled", "tank"):
            return (other.kind == self.kind and other.unit == self.unit
                    and other.value <= self.value)
        return other.kind == "frozen"

    def describe(self) -> str:
        """The class in plain words (what the command line prints)."""
        unit = " rad of spring deflection" if self.unit else ""
        return _DESCRIPTIONS[self.kind].format(value=self.value, unit=unit)

    def __str__(self) -> str:
        if self.kind in ("rate", "scheduled"):
            return f"{self.kind}:{self.value:g}"
        if self.kind == "tank" and (self.value > 0 or self.unit):
            return f"tank:{self.value:g}{self.unit}"
        return self.kind


def parse_gain_variation(text: str) -> GainVariation:
    """Parse ``frozen``, ``switching``, ``rate:R``, ``scheduled:L`` or ``tank[:T0 or :Drad]``.

    Parameters
    ----------
    text : str
        The gain class, as :class:`GainVariation` prints it.

    Returns
    -------
    GainVariation
        The parsed gain class.

    Raises
    ------
    ValueError
        One line naming the bad class or number (NaN included), quoting the text given.
    """
    kind, colon, number = str(text).strip().partition(":")
    if kind not in KINDS:
        raise ValueError(f"gain variation must be {_SYNTAX}, got {text!r}")
    if kind in ("frozen", "switching") and colon:
        raise ValueError(f"gain variation {kind} takes no number, got {text!r}")
    if kind in ("rate", "scheduled") and not number:
        raise ValueError(f"gain variation {kind} needs a number ({kind}:N), got {text!r}")
    if not colon:
        return GainVariation(kind)
    unit = "rad" if kind == "tank" and number.strip().endswith("rad") else ""
    try:
        value = float(number.strip().removesuffix("rad") if unit else number)
    except ValueError:
        value = math.nan
    if math.isnan(value):  # NaN too: it would read as "no number" (an empty tank)
        raise ValueError(f"gain variation {text!r}: {number!r} is not a number")
    return GainVariation(kind, value, unit)
