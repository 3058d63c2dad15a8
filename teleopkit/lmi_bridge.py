"""LMI certificates of remote gain sets, from the teleoperator's linearisation at rest.

A set of remote gains becomes a polytope of linear delay systems: every vertex of the gain
polytope (a product of one polygon per joint) times every configuration vertex of
:func:`~teleopkit.linearize.rest_systems`. :mod:`certify` then certifies the whole polytope for
delays ``0 <= T_l(t) <= T_l*``, ``0 <= T_r(t) <= T_r*`` (derivatives unrestricted):

* frozen gains: every fixed point of the polytope (parameter-dependent functional), which covers
  each constant gain in the set at each rest configuration;
* switching gains: one common functional at every vertex, which covers gains (and the
  configuration) changing arbitrarily fast inside the set. A rate bound is a special case of
  arbitrary switching, so ``rate:R`` is certified the same way (sound, not rate-specific).

The cost grows quickly with the number of vertices (``4^n`` gain vertices for a box of ``n``
joints, times ``2^(n (n-1) / 2)`` configurations): one Clarabel solve takes about 0.5 s at 2
vertices of the paper's 12-state system, 9 s at 8, and more than 10 minutes (2.7 GB) at 32, a
two-joint box. Polytopes above :data:`MAX_VERTICES` are refused with a clear error instead.
"""

from __future__ import annotations

from certify import Certificate, PolytopicDelaySystem, certify_delay, max_delay_certificate
from teleopkit.gains import GainPolytope
from teleopkit.linearize import rest_systems
from teleopkit.params import TeleoperatorParams

__all__ = ["LMI_METHOD", "MAX_VERTICES", "gain_set_system", "lmi_certificate", "lmi_delay_margin"]

MAX_VERTICES = 16
"""Largest polytope (gain vertices times configuration vertices) the bridge hands to the solver."""

LMI_METHOD = "rcc"
"""Default LMI: Lyapunov-Krasovskii with the reciprocally convex bound. On the paper's
teleoperator at one gain and configuration it certifies 1.42 s where the closed form gives
1.00 s and the scaled small-gain test 1.09 s; the Wirtinger functional reaches 2.28 s at several
times the cost."""


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
        Whether the gains (and the rest configuration) are constant or may switch arbitrarily.

    Returns
    -------
    certify.PolytopicDelaySystem
        Vertices: gain vertices times configuration vertices; delays ordered ``(T_l, T_r)``.

    Raises
    ------
    ValueError
        If the polytope is empty or has more than :data:`MAX_VERTICES` vertices.
    """
    actions = polytope.vertices()
    if actions.size == 0:
        raise ValueError("the gain set is empty: nothing to certify")
    systems = [system for action in actions for system in rest_systems(params, action)]
    if len(systems) > MAX_VERTICES:
        raise ValueError(
            f"the LMI over {len(systems)} vertices ({len(actions)} gain vertices x "
            f"{len(systems) // len(actions)} configurations) exceeds {MAX_VERTICES}: one solve "
            "would take many minutes; fix some joint's gains to a point or use the closed form")
    return PolytopicDelaySystem(tuple(systems), variation)


def lmi_certificate(params: TeleoperatorParams, polytope: GainPolytope, tl_max: float,
                    tr_max: float, variation: str = "frozen",
                    method: str = LMI_METHOD) -> Certificate:
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

    Returns
    -------
    certify.Certificate
        The LMI certificate (``certified`` is the verdict; solver failures are not certified).
    """
    return certify_delay(gain_set_system(params, polytope, variation), [tl_max, tr_max], method)


def lmi_delay_margin(params: TeleoperatorParams, polytope: GainPolytope,
                     variation: str = "frozen", method: str = LMI_METHOD,
                     rtol: float = 0.02) -> Certificate:
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

    Returns
    -------
    certify.Certificate
        Certificate at the largest certified bound, stored in ``margin`` (0 if none).
    """
    system = gain_set_system(params, polytope, variation)
    return max_delay_certificate(system, method, rtol=rtol, h_max=100.0)
