"""The safety layer's interface: what every projection onto a certified set offers.

Every remote gain that reaches the plant passes through a :class:`SafetyLayer` built on a
certificate (:func:`~teleopkit.safety.factory.layer_for`):
:class:`~teleopkit.safety.polytope.PolytopeLayer` for the classes whose set is a polytope (frozen,
switching, rate-bounded gains) and :class:`~teleopkit.safety.schedule.ScheduleLayer` for the
scheduled classes, whose set at each step depends on the episode so far. A layer owns that history:
:meth:`SafetyLayer.reset` starts an episode, :meth:`SafetyLayer.step` projects one control step's
raw gains and remembers what it applied, and :meth:`SafetyLayer.observe` takes the measurements a
tank is paid from.

A layer is total: a non-finite raw action yields a certified fallback, and every step reports
what it did (:class:`Projection`).
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from typing import NamedTuple

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.certification.scheduled_set import ScheduledSet

__all__ = ["FLAGS", "Fallback", "Projection", "SafetyLayer", "kkt_polish"]


class Fallback(enum.IntFlag):
    """What the safety layer did beyond an exact projection (flags, combinable).

    Attributes
    ----------
    NONE
        Exact projection of the raw action.
    NONFINITE_INPUT
        The raw action had NaN or inf: the previous action (projected) or, without a finite
        previous action, the layer's fixed interior point was applied.
    RATE_INFEASIBLE
        The rate bound could not be applied (the rate box around the previous action misses the
        set, or the previous action is not finite): projected onto the polytope alone.
    """

    NONE = 0
    NONFINITE_INPUT = 1
    RATE_INFEASIBLE = 2


FLAGS = tuple(Fallback(value) for value in range(4))
"""The :class:`Fallback` of each integer flag value (a lookup, cheaper than the enum call)."""


class Projection(NamedTuple):
    """What a :meth:`SafetyLayer.step` (one action or a batch) or a projection did.

    Attributes
    ----------
    action : ndarray, shape (2 n,) or (B, 2 n)
        Applied (certified) action.
    distance : float or ndarray, shape (B,)
        ``||action - raw||`` (``inf`` when the raw action was not finite).
    active : ndarray of bool, shape (m,) or (B, m)
        Rows of ``G`` that hold with equality (distance to the hyperplane within the layer's
        tolerance) at the applied action.
    rate_active : ndarray of bool, shape (2 n,) or (B, 2 n)
        Coordinates at their rate bound ``|a - a_prev| = rho T_s``.
    fallback : Fallback or ndarray of int, shape (B,)
        :class:`Fallback` flags (integers for a batch); zero means an exact projection.
    schedule : float or ndarray, shape (B,)
        Run-time state left after the step: the log budget (``scheduled:L``) or the tank level
        (``tank``); NaN for the classes without one.
    """

    action: np.ndarray
    distance: float | np.ndarray
    active: np.ndarray
    rate_active: np.ndarray
    fallback: Fallback | np.ndarray
    schedule: float | np.ndarray = math.nan


class SafetyLayer(ABC):
    """The projection of raw remote gains onto a certified set, one control step at a time.

    Attributes
    ----------
    certificate : GainCertificate or None
        The certificate the layer enforces (None for a layer built on a bare polytope).
    polytope : GainPolytope
        The certified polytope: every applied action lies in it.
    tol : float
        Tolerance of the active-constraint report.
    measures_energy : bool
        Whether :meth:`observe` needs the plant's measured energy (an energy tank).
    """

    certificate: GainCertificate | None = None
    polytope: GainPolytope
    tol: float
    measures_energy = False

    @property
    def dimension(self) -> int:
        """Dimension ``2 n`` of the action space."""
        return self.polytope.dimension

    @property
    @abstractmethod
    def labels(self) -> tuple[str, ...]:
        """What each entry of :attr:`Projection.active` stands for."""

    @property
    @abstractmethod
    def admissible_set(self) -> GainPolytope | ScheduledSet:
        """The static set the layer projects onto (a scheduled class adds its run-time floor)."""

    @property
    @abstractmethod
    def fallback_action(self) -> np.ndarray:
        """The fixed interior action applied when nothing finite is available (a copy)."""

    @abstractmethod
    def reset(self) -> None:
        """Start an episode: forget the applied actions (and refill a budget or tank)."""

    @abstractmethod
    def step(self, raw: np.ndarray) -> Projection:
        """Project one control step's raw actions and remember the applied ones.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions; NaN and inf are allowed (fallback).

        Returns
        -------
        Projection
            The applied actions and what the layer did (arrays with a batch axis for a batch,
            scalars for one action).
        """

    def observe(self, energy: np.ndarray, motor_speed_integral: np.ndarray) -> None:  # noqa: B027
        """Take the measurements at a sample (used by an energy tank; nothing here).

        Parameters
        ----------
        energy : ndarray, shape (B,)
            The remote arm's stored energy ``E_r`` in joules.
        motor_speed_integral : ndarray, shape (B, n)
            ``int_0^t theta_i'^2`` of each motor since the start of the episode.
        """

    def run_time_state(self, batch: int) -> np.ndarray:
        """The run-time state an agent observes beside the plant (none here).

        Parameters
        ----------
        batch : int
            Number of scenarios.

        Returns
        -------
        ndarray, shape (B, k)
            ``k = 0`` for a layer without run-time state.
        """
        return np.zeros((batch, 0))

    @abstractmethod
    def contains(self, actions: np.ndarray) -> np.ndarray:
        """Whether actions lie in the certified set (and, mid-episode, its run-time part).

        Parameters
        ----------
        actions : ndarray, shape (..., 2 n)
            Gain vectors.

        Returns
        -------
        ndarray of bool, shape (...)
            Membership of each action.
        """

    @abstractmethod
    def project_set(self, raw: np.ndarray) -> np.ndarray:
        """The nearest points of the static set, leaving the episode's history alone.

        What constant gains can be: the set a fixed-gain baseline or a search chooses from.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions (finite).

        Returns
        -------
        ndarray, the shape of ``raw``
            Their projections.
        """

    def active_labels(self, active: np.ndarray) -> tuple[str, ...]:
        """Labels of the active constraints of one sample.

        Parameters
        ----------
        active : ndarray of bool, shape (m,)
            :attr:`Projection.active` of one sample.

        Returns
        -------
        tuple of str
            The labels of the active constraints (:attr:`labels`).
        """
        return tuple(label for label, on in zip(self.labels, active, strict=True) if on)

    def _actions(self, values: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
        array = np.ascontiguousarray(values, dtype=np.float64)
        if array.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
        return array


def kkt_polish(g: np.ndarray, h: np.ndarray, raw: np.ndarray, approx: np.ndarray,
               tol: float = 1e-4) -> np.ndarray | None:
    """Exact projection of ``raw`` onto ``{g a <= h}`` from an approximate one.

    Rows within distance ``tol (1 + |raw - approx|)`` of ``approx`` start as equalities (an
    interior-point solution's error grows with the distance projected over: from 200 gain
    units away Clarabel left a bound at 1e-4); the row with the most negative multiplier is
    dropped until all are non-negative. The least-squares solution is returned if it is also
    feasible and its rows are tight (then it satisfies the KKT conditions), else None.

    Parameters
    ----------
    g : ndarray, shape (m, d)
        Constraint normals.
    h : ndarray, shape (m,)
        Constraint offsets.
    raw : ndarray, shape (d,)
        The point projected.
    approx : ndarray, shape (d,)
        An approximate projection (an interior-point solution).
    tol : float
        Distance below which a row starts as an equality, per unit of distance projected.

    Returns
    -------
    ndarray or None
        The exact projection, or None if the polish does not find a KKT point.
    """
    norms = np.linalg.norm(g, axis=1)
    reach = 1.0 + np.linalg.norm(raw - approx)
    active = np.flatnonzero(g @ approx - h >= -tol * reach * norms)
    while True:
        g_a = g[active]
        multipliers = np.linalg.lstsq(g_a @ g_a.T, g_a @ raw - h[active], rcond=None)[0]
        if active.size == 0 or multipliers.min() >= -1e-9:
            break
        active = np.delete(active, np.argmin(multipliers))
    exact = raw - g_a.T @ multipliers
    slack = 1e-10 * norms * (1.0 + np.abs(exact).max())
    feasible = np.all(g @ exact - h <= slack)
    tight = np.all(np.abs(g_a @ exact - h[active]) <= slack[active])
    return exact if feasible and tight else None
