"""Certificate objects: verdict, assumptions, solver data, JSON round trip, re-check."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from certify.channels import Channels
from certify.check import RTOL, residuals, variables_valid
from certify.conditions import lower_bounds
from certify.methods import get_method
from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.system_data import system_data
from certify.uncertainty import AffineUncertainty

__all__ = ["Certificate"]


@dataclass(frozen=True, eq=False)
class Certificate:
    """Outcome of an LMI stability test for given delay bounds.

    Parameters
    ----------
    certified : bool
        Whether the LMIs were solved and re-checked in numpy with a positive margin.
    method : str
        LMI method name (``jensen``, ``rcc``, ``wirtinger`` or ``io``).
    delay_bounds : tuple of float
        Upper bound ``h_i`` of each delay.
    mu : float or None
        Delay-derivative bound (``None`` fast-varying, ``0.0`` constant delays).
    assumptions : tuple of str
        What the certificate covers (delay class, system class, method).
    system : PolytopicDelaySystem
        The certified system (one or more vertices).
    solver : str
        Solver name.
    status : str
        Solver status.
    matrices : Mapping[str, numpy.ndarray]
        Decision matrices returned by the solver (empty if not certified).
    channels : tuple of numpy.ndarray
        Output map ``C_i`` of each delay channel (``y_i = C_i x``, ``A_i = A_i C_i^T C_i``).
    residuals : Mapping[str, float]
        Relative eigenvalue margin of each condition (positive means satisfied).
    margin : float or None
        Largest delay scale found by :func:`certify.max_delay_certificate`, if any.
    scaling : tuple of float
        State scales ``d`` of the coordinates ``x = diag(d) z`` that ``matrices`` and
        ``channels`` refer to (:meth:`PolytopicDelaySystem.scaled`); empty means ``d = 1``.
    delay_lower : tuple of float
        Lower bound ``l_i`` of each delay (``l_i <= tau_i(t) <= h_i``); empty means 0.
    eliminated : tuple of int
        Rows of the descriptor relation whose kernel the conditions are posed on instead of
        multiplying them by the slack (:func:`certify.system_data.eliminable_rows`); empty: none.
    """

    certified: bool
    method: str
    delay_bounds: tuple[float, ...]
    mu: float | None
    assumptions: tuple[str, ...]
    system: PolytopicDelaySystem
    solver: str = "CLARABEL"
    status: str = ""
    matrices: Mapping[str, NDArray[np.float64]] = field(default_factory=dict)
    channels: tuple[NDArray[np.float64], ...] = ()
    residuals: Mapping[str, float] = field(default_factory=dict)
    margin: float | None = None
    scaling: tuple[float, ...] = ()
    delay_lower: tuple[float, ...] = ()
    eliminated: tuple[int, ...] = ()

    def verify(self, rtol: float = RTOL) -> bool:
        """Re-check every LMI in numpy from the stored matrices and system.

        Parameters
        ----------
        rtol : float, optional
            Smallest accepted relative eigenvalue margin.

        Returns
        -------
        bool
            ``True`` if the certificate claims stability and all conditions hold.
        """
        if not self.certified:
            return False
        try:
            method = get_method(self.method)
            if self.delay_lower:
                lower = lower_bounds(self.delay_lower, len(self.delay_bounds))
                if any(h < low for h, low in zip(self.delay_bounds, lower, strict=True)):
                    return False
                method = method.with_lower(lower)
            system = self.system.scaled(self.scaling) if self.scaling else self.system
            ch = Channels(system.n, tuple(self.channels))
            if len(self.delay_bounds) != system.m or not ch.valid_for(system):
                return False
            data = system_data(method, system, ch, self.mu, self.eliminated)
        except ValueError:
            return False
        if not variables_valid(method, system, ch, self.mu, self.matrices, data):
            return False
        res = residuals(method, system, ch, self.matrices, self.delay_bounds, self.mu, data)
        return all(r >= rtol for r in res.values())

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary (arrays as nested lists).

        Returns
        -------
        dict
            All fields.
        """
        return {
            "certified": self.certified,
            "method": self.method,
            "delay_bounds": list(self.delay_bounds),
            "mu": self.mu,
            "assumptions": list(self.assumptions),
            "system": [v.to_dict() for v in self.system.vertices],
            "variation": self.system.variation,
            "uncertainty": (None if self.system.uncertainty is None
                            else self.system.uncertainty.to_dict()),
            "solver": self.solver,
            "status": self.status,
            "matrices": {k: v.tolist() for k, v in self.matrices.items()},
            "channels": [c.tolist() for c in self.channels],
            "residuals": dict(self.residuals),
            "margin": self.margin,
            "scaling": list(self.scaling),
            "delay_lower": list(self.delay_lower),
            "eliminated": list(self.eliminated),
        }

    def to_json(self, indent: int | None = None) -> str:
        """Serialise to JSON.

        Parameters
        ----------
        indent : int or None, optional
            Indentation passed to :func:`json.dumps`.

        Returns
        -------
        str
            The JSON text.
        """
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Certificate:
        """Rebuild a certificate from :meth:`to_dict` output.

        Parameters
        ----------
        data : Mapping[str, Any]
            The dictionary.

        Returns
        -------
        Certificate
            The certificate (not re-verified; call :meth:`verify`).
        """
        vertices = tuple(LinearDelaySystem.from_dict(v) for v in data["system"])
        uncertainty = data.get("uncertainty")
        system = PolytopicDelaySystem(
            vertices, str(data.get("variation", "switching")),
            None if uncertainty is None else AffineUncertainty.from_dict(uncertainty))
        return cls(
            certified=bool(data["certified"]),
            method=str(data["method"]),
            delay_bounds=tuple(float(x) for x in data["delay_bounds"]),
            mu=None if data["mu"] is None else float(data["mu"]),
            assumptions=tuple(data["assumptions"]),
            system=system,
            solver=str(data["solver"]),
            status=str(data["status"]),
            matrices={k: np.asarray(v, dtype=np.float64) for k, v in data["matrices"].items()},
            channels=tuple(
                np.asarray(c, dtype=np.float64).reshape(-1, system.n) for c in data["channels"]
            ),
            residuals={k: float(v) for k, v in data["residuals"].items()},
            margin=None if data["margin"] is None else float(data["margin"]),
            scaling=tuple(float(x) for x in data.get("scaling", ())),
            delay_lower=tuple(float(x) for x in data.get("delay_lower", ())),
            eliminated=tuple(int(x) for x in data.get("eliminated", ())),
        )

    @classmethod
    def from_json(cls, text: str) -> Certificate:
        """Parse a certificate from :meth:`to_json` output.

        Parameters
        ----------
        text : str
            The JSON text.

        Returns
        -------
        Certificate
            The certificate.
        """
        return cls.from_dict(json.loads(text))
