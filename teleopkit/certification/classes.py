"""Gain classes: how the remote gains may vary inside a certified set.

``frozen``: every constant gain of the set; ``switching``: gains changing arbitrarily fast
inside it; ``rate:R``: gains whose rate of change is at most ``R`` per second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["GainVariation", "parse_gain_variation"]


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
