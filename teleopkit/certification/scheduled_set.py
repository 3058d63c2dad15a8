r"""The admissible set of a scheduled gain class, as certification hands it to the safety layer.

A ``scheduled:L`` or ``tank[:T0]`` certificate allows, at every control step, the remote gains

.. math::

    K_r^i = \kappa s_i, \quad \kappa_{low} \le \kappa \le \kappa_{high}, \quad
    B_{low}^i \le B_r^i \le B_{high}^i, \quad B_r^i \ge \rho_i s_i \kappa + \beta_i ,

plus a floor on ``kappa`` that its run-time rule sets from the history of the episode: a log
budget of falls (``"budget"``) or an energy tank (``"tank"``). :class:`ScheduledSet` carries
exactly these numbers; a certificate keeps its serialised form in ``details["set"]`` and gives it
back as :attr:`~teleopkit.certification.gain_certificate.GainCertificate.scheduled_set`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["RULES", "ScheduledSet"]

RULES = ("budget", "tank")
"""The run-time rules: a log budget of falls of ``kappa``, or an energy tank that pays them."""


@dataclass(frozen=True)
class ScheduledSet:
    """The set of a scheduled class: common shape, cone, damping box, ``kappa`` range, rule.

    Parameters
    ----------
    shape : tuple of float
        ``s_i``: the stiffness is ``K_r^i = kappa s_i`` (``s_1 = 1``).
    cone : tuple of float
        ``rho_i``: the cone is ``B_r^i >= rho_i K_r^i + offset_i``.
    offset : tuple of float
        ``beta_i``: the closed form's margin, in damping units.
    damping_low, damping_high : tuple of float
        The damping box of each joint.
    kappa_low, kappa_high : float
        The static interval of ``kappa`` (common shape inside the box and the cone).
    rule : {"budget", "tank"}
        How falls of ``kappa`` are paid.
    initial : float
        The log budget ``L`` per episode, or the tank's initial level ``T0``.
    refill : float
        Fraction of the proven dissipation that refills the tank (0 for a budget).
    """

    shape: tuple[float, ...]
    cone: tuple[float, ...]
    offset: tuple[float, ...]
    damping_low: tuple[float, ...]
    damping_high: tuple[float, ...]
    kappa_low: float
    kappa_high: float
    rule: str
    initial: float
    refill: float = 0.0

    def __post_init__(self) -> None:
        n = len(self.shape)
        if any(len(getattr(self, name)) != n for name in
               ("cone", "offset", "damping_low", "damping_high")):
            raise ValueError("a scheduled set needs one shape, cone, offset and damping range "
                             "per joint")
        if self.rule not in RULES:
            raise ValueError(f"a scheduled set's rule is budget or tank, got {self.rule!r}")
        numbers = (*self.shape, *self.cone, *self.offset, *self.damping_low, *self.damping_high,
                   self.kappa_low, self.kappa_high, self.initial, self.refill)
        if not all(math.isfinite(x) for x in numbers):
            raise ValueError("a scheduled set's numbers must be finite")
        if min(self.shape) <= 0 or min(self.cone) <= 0:
            raise ValueError("a scheduled set's shape and cone must be positive")

    @property
    def is_empty(self) -> bool:
        """Whether no common-shape stiffness lies in the box and the cone."""
        return self.kappa_low > self.kappa_high

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return len(self.shape)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``shape, cone, offset, damping_low, damping_high`` as float arrays."""
        return tuple(np.array(getattr(self, name), dtype=float) for name in  # type: ignore
                     ("shape", "cone", "offset", "damping_low", "damping_high"))

    def kappa(self, gains: np.ndarray) -> np.ndarray:
        """The scheduled variable ``kappa = K_r^1 / s_1`` of gain vectors.

        Parameters
        ----------
        gains : ndarray, shape (..., 2 n)
            ``[K_r..., B_r...]``.

        Returns
        -------
        ndarray, shape (...)
            ``kappa``.
        """
        return np.asarray(gains, dtype=float)[..., 0] / self.shape[0]

    def dissipation_rates(self, gains: np.ndarray) -> np.ndarray:
        """Coefficients ``B_r^i / kappa - s_i rho_i`` of ``theta_i'^2`` in the proven dissipation.

        Parameters
        ----------
        gains : ndarray, shape (..., 2 n)
            Gains of the set.

        Returns
        -------
        ndarray, shape (..., n)
            Non-negative inside the cone.
        """
        gains = np.asarray(gains, dtype=float)
        shape, cone = np.array(self.shape), np.array(self.cone)
        return gains[..., self.n_joints:] / self.kappa(gains)[..., None] - shape * cone

    def corners(self) -> np.ndarray:
        """The extreme gains of the set, shape ``(4, 2 n)``.

        Both ends of ``kappa``, with the lowest and the highest damping each: what a check
        against the certificate's polytope needs.
        """
        shape, cone, offset, low, high = self.arrays()
        rows = []
        for kappa in (self.kappa_low, self.kappa_high):
            floor = np.maximum(low, cone * shape * kappa + offset)
            rows += [np.concatenate([kappa * shape, floor]), np.concatenate([kappa * shape, high])]
        return np.array(rows)

    def centre(self) -> np.ndarray:
        """An interior action: mid ``kappa`` and mid damping of the cone at that ``kappa``."""
        shape, cone, offset, low, high = self.arrays()
        kappa = 0.5 * (self.kappa_low + self.kappa_high)
        floor = np.maximum(low, cone * shape * kappa + offset)
        return np.concatenate([kappa * shape, 0.5 * (floor + high)])

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON)."""
        return {key: list(value) if isinstance(value, tuple) else value
                for key, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ScheduledSet:
        """Inverse of :meth:`to_dict`.

        Parameters
        ----------
        data : dict
            As :meth:`to_dict` writes it.

        Returns
        -------
        ScheduledSet
            The set.

        Raises
        ------
        ValueError
            On a missing or malformed field.
        """
        try:
            return cls(**{key: tuple(float(v) for v in value)  # type: ignore[arg-type]
                          if isinstance(value, list) else value for key, value in data.items()})
        except TypeError as error:
            raise ValueError(f"malformed scheduled set: {error}") from None
