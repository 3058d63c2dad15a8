"""LMI certificates of remote gain sets, from the teleoperator's linearisation at rest.

A set of remote gains (a product of one polygon per joint) and the configuration vertices of
:func:`~teleopkit.model.linearize.rest_systems` become a polytope of linear delay systems, which
:mod:`certify` certifies for delays ``T_l_min <= T_l(t) <= T_l*``, ``T_r_min <= T_r(t) <= T_r*``
(lower bounds 0 by default, derivatives unrestricted). The rest configuration is frozen: one
functional per configuration vertex, which covers the linearisation at every rest configuration.
The gains enter in one of two ways:

* enumerated (frozen gains, at most :data:`MAX_VERTICES` gain vertices times configurations):
  every vertex is a system and the functional depends on the gains too, which covers each
  constant gain in the set. This is the least conservative certificate for constant gains, but
  its cost grows with ``4^n`` gain vertices (one Clarabel solve takes about 0.5 s at 2
  vertices of the paper's 12-state system, 9 s at 8, and more than 10 minutes at 32);
* as an affine uncertainty (switching gains, and frozen gains above :data:`MAX_VERTICES`):
  each gain is a rank-one change of the motor equations, handled by full-block multipliers
  (:mod:`certify.uncertainty`) at the cost of 2 n extra rows per LMI instead of more LMIs.
  One functional then serves every gain in the set, which covers gains switching
  arbitrarily fast, and therefore constant ones as well (more conservatively). A rate bound
  is a special case of arbitrary switching, so ``rate:R`` is certified the same way (sound,
  not rate-specific).

For constant gains of a large set, :func:`teleopkit.certification.lmi.cover.cover_certificate` is
less conservative than one multiplier certificate: it covers the set with cells certified here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from certify import (
    AffineUncertainty,
    Certificate,
    Direction,
    PolytopicDelaySystem,
    certify_delay,
    max_delay_certificate,
)
from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.model.linearize import rest_systems
from teleopkit.model.params import TeleoperatorParams

__all__ = ["CHANNELS", "LMI_METHOD", "MAX_VERTICES", "NO_LOWER", "VERTEX_RETRY", "DelayQuestion",
           "enumerated", "gain_names", "gain_set_system", "lmi_certificate", "lmi_delay_margin",
           "vertex_certificate"]

MAX_VERTICES = 16
"""Largest enumerated polytope (gain vertices times configuration vertices) for frozen gains;
larger frozen sets are certified through the affine-uncertainty form."""

LMI_METHOD = "rcc"
"""Default LMI: Lyapunov-Krasovskii with the reciprocally convex bound. On the paper's
teleoperator at one gain and configuration it certifies 1.42 s where the closed form gives
1.00 s and the scaled small-gain test 1.09 s; the Wirtinger functional reaches 2.28 s at several
times the cost."""


NO_LOWER = (0.0, 0.0)
"""Lower delay bounds ``(T_l_min, T_r_min)`` by default: delays from 0."""

VERTEX_RETRY = "accurate"
"""A gain vertex alone retries in balanced coordinates only after an accurate solve
(:class:`certify.solve.LMIProblem`). On the paper's two-joint teleoperator (440 solves: random
gains of the box ``K_r`` in [1, 50], ``B_r`` in [1, 150], bounds 1 to 2 times the closed form's
margin) none of the 230 solves that ended ``optimal_inaccurate`` was certified by the retry,
while 10 of the 34 accurate failures were."""

CHANNELS = "reduced"
"""The functional acts on the transmitted positions only (:mod:`certify.channels`). This is a
deliberate trade: on the one-joint teleoperator (RCC, one constant gain at every rest
configuration) the full-state functional certifies 3-5 % larger delay margins (1.61 s against
1.56 s at ``K_r = 10, B_r = 30``; 3.27 s against 3.10 s at ``K_r = 5, B_r = 60``) at about ten
times the cost per solve, which the two-joint covers cannot afford."""


def gain_names(n_joints: int) -> tuple[str, ...]:
    """Names of the remote gains in action order, ``K_r1, ..., K_rn, B_r1, ..., B_rn``.

    Parameters
    ----------
    n_joints : int
        Number of joints.

    Returns
    -------
    tuple of str
        The names.
    """
    return (tuple(f"K_r{j + 1}" for j in range(n_joints))
            + tuple(f"B_r{j + 1}" for j in range(n_joints)))


def _gain_uncertainty(params: TeleoperatorParams, actions: np.ndarray) -> AffineUncertainty:
    """Each remote gain as a direction of the rest systems (which are affine in the gains)."""
    size = 2 * params.n_joints
    origin = rest_systems(params, np.zeros(size))[0]
    directions = []
    for unit in np.eye(size):
        moved = rest_systems(params, unit)[0]
        directions.append(Direction(moved.A0 - origin.A0,
                                    tuple(a - b for a, b in zip(moved.A, origin.A, strict=True)),
                                    moved.E_matrix - origin.E_matrix))
    return AffineUncertainty(tuple(directions), actions, gain_names(params.n_joints))


def enumerated(params: TeleoperatorParams, polytope: GainPolytope) -> bool:
    """Whether frozen gains of ``polytope`` are certified by enumerating its vertices.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains.

    Returns
    -------
    bool
        ``True`` if gain vertices times configurations are at most :data:`MAX_VERTICES`.
    """
    configurations = rest_systems(params, np.zeros(polytope.dimension))
    return len(polytope.vertices()) * len(configurations) <= MAX_VERTICES


def gain_set_system(params: TeleoperatorParams, polytope: GainPolytope,
                    variation: str) -> PolytopicDelaySystem:
    """The linearised teleoperator over a gain polytope, as a polytope of delay systems.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains (a product of one polygon per joint).
    variation : {"frozen", "switching"}
        Whether the gains are constant or may switch arbitrarily (see the module docstring).

    Returns
    -------
    certify.PolytopicDelaySystem
        Frozen over the configuration vertices; the gains enumerated (frozen gains, small
        sets) or as an affine uncertainty. Delays ordered ``(T_l, T_r)``.

    Raises
    ------
    ValueError
        If the polytope is empty or ``variation`` is unknown.
    """
    if variation not in ("frozen", "switching"):
        raise ValueError(f"variation must be 'frozen' or 'switching', got {variation!r}")
    actions = polytope.vertices()
    if actions.size == 0:
        raise ValueError("the gain set is empty: nothing to certify")
    if variation == "frozen" and enumerated(params, polytope):
        systems = [system for action in actions for system in rest_systems(params, action)]
        return PolytopicDelaySystem(tuple(systems), "frozen")
    configurations = rest_systems(params, np.zeros(actions.shape[1]))
    return PolytopicDelaySystem(tuple(configurations), "frozen",
                                _gain_uncertainty(params, actions))


def lmi_certificate(params: TeleoperatorParams, polytope: GainPolytope, tl_max: float,
                    tr_max: float, variation: str = "frozen", method: str = LMI_METHOD,
                    delay_lower: tuple[float, float] = NO_LOWER,
                    retry: str = "always", threads: int = 1) -> Certificate:
    """Certify a gain polytope for the delay bounds ``(T_l*, T_r*)``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains to certify.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : {"frozen", "switching"}
        Gain class (see the module docstring).
    method : str
        A :data:`certify.METHODS` name.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)``: the delays lie in ``[T_i_min, T_i*]``.
    retry : {"always", "accurate"}
        When a failed solve is tried again in balanced coordinates
        (:class:`certify.solve.LMIProblem`).
    threads : int
        Most threads of the solver's linear algebra (0: its default, every core). One by
        default: on these LMIs a second thread makes a solve slower.

    Returns
    -------
    certify.Certificate
        The LMI certificate (``certified`` is the verdict; solver failures are not certified).
    """
    return certify_delay(gain_set_system(params, polytope, variation), [tl_max, tr_max], method,
                         lower=list(delay_lower), channels=CHANNELS, retry=retry,
                         threads=threads)


def lmi_delay_margin(params: TeleoperatorParams, polytope: GainPolytope,
                     variation: str = "frozen", method: str = LMI_METHOD,
                     rtol: float = 0.02,
                     delay_lower: tuple[float, float] = NO_LOWER, h_max: float = 100.0,
                     h_min: float = 0.0, threads: int = 1) -> Certificate:
    """Largest common delay bound ``T* = T_l* = T_r*`` certified for the whole polytope.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Remote gains.
    variation : {"frozen", "switching"}
        Gain class.
    method : str
        A :data:`certify.METHODS` name.
    rtol : float
        Relative tolerance of the bisection.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)`` kept while ``T*`` grows.
    h_max : float
        Largest bound tried (a known upper limit shortens the search).
    h_min : float
        Bounds less than this above the lower ones are not searched (0 if none above).
    threads : int
        Most threads of the solver's linear algebra (0: its default, every core). One by
        default: on these LMIs a second thread makes a solve slower.

    Returns
    -------
    certify.Certificate
        Certificate at the largest certified bound, stored in ``margin`` (0 if none). For
        frozen gains beyond :func:`enumerated` it is the margin of the whole set with gains
        switching, a lower bound of the frozen one.
    """
    system = gain_set_system(params, polytope, variation)
    return max_delay_certificate(system, method, rtol=rtol, h_max=h_max, lower=list(delay_lower),
                                 channels=CHANNELS, h_min=h_min, threads=threads)


def _vertex_system(params: TeleoperatorParams, action: np.ndarray) -> PolytopicDelaySystem:
    """One constant gain at every configuration vertex (frozen)."""
    return PolytopicDelaySystem(tuple(rest_systems(params, np.asarray(action, dtype=float))),
                                "frozen")


def vertex_certificate(params: TeleoperatorParams, action: np.ndarray, tl_max: float,
                       tr_max: float, method: str = LMI_METHOD,
                       delay_lower: tuple[float, float] = NO_LOWER,
                       threads: int = 1) -> Certificate:
    """Certify one constant gain vector alone for the delay bounds ``(T_l*, T_r*)``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    action : ndarray, shape (2 n,)
        Remote gains ``[K_r..., B_r...]``.
    tl_max, tr_max : float
        Delay bounds in seconds.
    method : str
        A :data:`certify.METHODS` name.
    delay_lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)``.
    threads : int
        Most threads of the solver's linear algebra (0: its default, every core). One by
        default: on these LMIs a second thread makes a solve slower.

    Returns
    -------
    certify.Certificate
        The LMI certificate of the gain at every rest configuration (retried in balanced
        coordinates as :data:`VERTEX_RETRY` says).
    """
    return certify_delay(_vertex_system(params, action), [tl_max, tr_max], method,
                         lower=list(delay_lower), channels=CHANNELS, retry=VERTEX_RETRY,
                         threads=threads)


@dataclass(frozen=True)
class DelayQuestion:
    """One LMI question about gains: stable on this plant for these delays, by this method.

    What every cell and gain vertex of a cover is asked
    (:func:`~teleopkit.certification.lmi.cover.cover_certificate`), and what a
    :class:`~teleopkit.certification.lmi.cells.CellMemo` holds verdicts of; the gain set is
    given to each call.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    bounds : tuple of float
        Delay bounds ``(T_l*, T_r*)`` in seconds.
    lower : tuple of float
        Lower delay bounds ``(T_l_min, T_r_min)``: the delays lie in ``[T_i_min, T_i*]``.
    method : str
        A :data:`certify.METHODS` name (the LMI formulation).
    """

    params: TeleoperatorParams
    bounds: tuple[float, float]
    lower: tuple[float, float] = NO_LOWER
    method: str = LMI_METHOD

    def __post_init__(self) -> None:
        object.__setattr__(self, "bounds", tuple(float(b) for b in self.bounds))
        object.__setattr__(self, "lower", tuple(float(b) for b in self.lower))

    def at(self, bound: float) -> DelayQuestion:
        """The same question for the common delay bound ``T_l* = T_r* = bound``.

        Parameters
        ----------
        bound : float
            Delay bound in seconds.

        Returns
        -------
        DelayQuestion
            The question with its bounds replaced.
        """
        return DelayQuestion(self.params, (bound, bound), self.lower, self.method)

    def cell(self, polytope: GainPolytope, variation: str = "frozen", retry: str = "always",
             threads: int = 1) -> Certificate:
        """:func:`lmi_certificate` of a gain polytope for this question.

        Parameters
        ----------
        polytope : GainPolytope
            Remote gains.
        variation : {"frozen", "switching"}
            Gain class.
        retry : {"always", "accurate"}
            When a failed solve is tried again in balanced coordinates.
        threads : int
            Most threads of the solver's linear algebra (0: its default).

        Returns
        -------
        certify.Certificate
            The LMI certificate.
        """
        return lmi_certificate(self.params, polytope, *self.bounds, variation, self.method,
                               self.lower, retry, threads)

    def vertex(self, action: np.ndarray, threads: int = 1) -> Certificate:
        """:func:`vertex_certificate` of one constant gain vector for this question.

        Parameters
        ----------
        action : ndarray, shape (2 n,)
            Remote gains ``[K_r..., B_r...]``.
        threads : int
            Most threads of the solver's linear algebra (0: its default).

        Returns
        -------
        certify.Certificate
            The LMI certificate of the gain at every rest configuration.
        """
        return vertex_certificate(self.params, action, *self.bounds, self.method, self.lower,
                                  threads)
