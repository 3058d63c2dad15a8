"""Closed-form delay-dependent condition of Nuño et al. for P+d teleoperators.

For the nonlinear teleoperator with joint flexibility, any passive operator and environment, and
constant gains, the P+d laws are stable for all delays ``0 <= T_l(t) <= T_l*``,
``0 <= T_r(t) <= T_r*`` if, per joint,

.. math::

    4 B_l B_r > (T_l^* + T_r^*)^2 K_l K_r .

With ``K_l, B_l`` fixed this is a half-plane in ``(K_r, B_r)``, so together with gain bounds the
admissible set is a polytope. (A variant with ``T_l*^2 + T_r*^2`` circulates in the literature; it
is unsound and not offered.)
"""

from __future__ import annotations

import math

import numpy as np

from teleopkit.gains import GainBox, GainPolytope
from teleopkit.params import TeleoperatorParams

__all__ = ["nuno_delay_margin", "nuno_joint_margins", "nuno_margins", "nuno_polytope"]

ASSUMPTIONS = (
    "nonlinear teleoperator with elastic remote joints (no linearisation)",
    "any passive operator and environment",
    "time-varying delays 0 <= T_i(t) <= T_i*, derivative unrestricted",
    "constant (frozen) remote gains",
)


def _check_bounds(tl_max: float, tr_max: float) -> None:
    for name, value in (("T_l*", tl_max), ("T_r*", tr_max)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"delay bound {name} must be positive and finite, got {value}")


def _gain_products(params: TeleoperatorParams,
                   actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``K_l K_r`` and ``B_l B_r`` of each joint for remote gains ``[K_r..., B_r...]``."""
    n = params.n_joints
    actions = np.asarray(actions, dtype=float)
    return (np.array(params.local_gains.stiffness) * actions[..., :n],
            np.array(params.local_gains.damping) * actions[..., n:])


def nuno_margins(params: TeleoperatorParams, actions: np.ndarray, tl_max: float,
                 tr_max: float) -> np.ndarray:
    """Slack ``4 B_l B_r - (T_l* + T_r*)^2 K_l K_r`` of each joint (positive means satisfied).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (local gains ``K_l, B_l``).
    actions : ndarray, shape (..., 2 n)
        Remote gains ``[K_r..., B_r...]``.
    tl_max, tr_max : float
        Delay bounds in seconds.

    Returns
    -------
    ndarray, shape (..., n)
        Slack per joint.
    """
    _check_bounds(tl_max, tr_max)
    stiffness, damping = _gain_products(params, actions)
    return 4 * damping - (tl_max + tr_max) ** 2 * stiffness


def nuno_polytope(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                  eps: float = 1e-6) -> GainPolytope:
    """Gains of ``box`` that satisfy the closed-form condition with slack at least ``eps``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        User's gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    eps : float
        Required slack (makes the strict inequality robust to rounding).

    Returns
    -------
    GainPolytope
        ``box`` intersected with one half-plane per joint.
    """
    _check_bounds(tl_max, tr_max)
    n = params.n_joints
    kl, bl = params.local_gains.stiffness, params.local_gains.damping
    normals = np.zeros((n, 2 * n))
    for i in range(n):
        normals[i, i] = (tl_max + tr_max) ** 2 * kl[i]
        normals[i, n + i] = -4 * bl[i]
    labels = tuple(f"Nuño joint {i + 1}: 4 B_l B_r >= (T_l*+T_r*)^2 K_l K_r" for i in range(n))
    return GainPolytope.from_box(box).intersect(normals, np.full(n, -eps), labels)


def nuno_joint_margins(params: TeleoperatorParams, actions: np.ndarray) -> np.ndarray:
    """Largest common bound ``T* = T_l* = T_r*`` each joint meets at the given gains.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (local gains ``K_l, B_l``).
    actions : ndarray, shape (..., 2 n)
        Remote gains ``[K_r..., B_r...]``.

    Returns
    -------
    ndarray, shape (..., n)
        ``sqrt(B_l B_r / (K_l K_r))`` per joint (``inf`` where ``K_l K_r = 0``).
    """
    stiffness, damping = _gain_products(params, actions)
    with np.errstate(divide="ignore"):
        return np.where(stiffness > 0, np.sqrt(damping / stiffness), np.inf)


def nuno_delay_margin(params: TeleoperatorParams, box: GainBox) -> float:
    """Largest common bound ``T* = T_l* = T_r*`` for which the whole box meets the condition.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        Gain ranges.

    Returns
    -------
    float
        ``min_i sqrt(B_l B_r,min / (K_l K_r,max))`` (the supremum; ``inf`` when every ``K`` is 0).
    """
    worst = [k[1] for k in box.kr] + [b[0] for b in box.br]
    return float(nuno_joint_margins(params, np.asarray(worst)).min())
