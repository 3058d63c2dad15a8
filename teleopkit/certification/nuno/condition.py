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

import numpy as np

from teleopkit.certification.delay_bounds import check_delay_bounds
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.records import plant_record

__all__ = ["ASSUMPTIONS", "NUNO_EPS", "RATIO_CAVEAT", "certify_frozen", "nuno_delay_margin",
           "nuno_joint_margins", "nuno_polytope", "nuno_slack", "weakest_first", "worst_vertex"]

ASSUMPTIONS = (
    "nonlinear teleoperator with elastic remote joints (no linearisation)",
    "any passive operator and environment (torque-controlled arms, no torque saturation)",
    "time-varying delays 0 <= T_i(t) <= T_i*, derivative unrestricted",
    "constant (frozen) remote gains",
)

RATIO_CAVEAT = (
    "proven (Nuño et al.) for K_r of the shape of K_l (the same ratio K_r^i / K_l^i on every "
    "joint); other per-joint ratios are applied without a published proof for the nonlinear "
    "plant, checked on the linearisation by LMI covers and on the nonlinear plant by "
    "falsification only")
"""Added to a frozen closed-form certificate whose box allows different per-joint ratios."""

NUNO_EPS = 1e-6
"""Slack ``eps`` of the strict inequality in the certified polytope,
``4 B_l B_r >= (T_l* + T_r*)^2 K_l K_r + eps`` (robust to rounding)."""


def _gain_products(params: TeleoperatorParams,
                   actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``K_l K_r`` and ``B_l B_r`` of each joint for remote gains ``[K_r..., B_r...]``."""
    n = params.n_joints
    actions = np.asarray(actions, dtype=float)
    return (np.array(params.local_gains.stiffness) * actions[..., :n],
            np.array(params.local_gains.damping) * actions[..., n:])


def nuno_slack(params: TeleoperatorParams, actions: np.ndarray, tl_max: float,
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
    check_delay_bounds(tl_max, tr_max)
    stiffness, damping = _gain_products(params, actions)
    return 4 * damping - (tl_max + tr_max) ** 2 * stiffness


def nuno_polytope(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                  eps: float = NUNO_EPS) -> GainPolytope:
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
    check_delay_bounds(tl_max, tr_max)
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


def weakest_first(params: TeleoperatorParams, actions: np.ndarray) -> np.ndarray:
    """Order of gain vectors by their closed-form margin, smallest first.

    Ties (the margin is the smallest over joints) go to the gains whose other joints' margins
    are smallest too.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    actions : ndarray, shape (V, 2 n)
        Remote gains, one vector per row (for example the vertices of a gain set).

    Returns
    -------
    ndarray, shape (V,)
        Row indices, the weakest first.
    """
    ranks = np.sort(nuno_joint_margins(params, actions), axis=1)
    return np.lexsort(ranks.T[::-1])


def worst_vertex(box: GainBox) -> np.ndarray:
    """The corner of a box where the closed form is tightest: largest ``K_r``, smallest ``B_r``.

    Parameters
    ----------
    box : GainBox
        Gain ranges.

    Returns
    -------
    ndarray, shape (2 n,)
        ``[K_r,max..., B_r,min...]``.
    """
    return np.concatenate([box.upper[:box.n_joints], box.lower[box.n_joints:]])


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
    return float(nuno_joint_margins(params, worst_vertex(box)).min())


def certify_frozen(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                   variation: GainVariation) -> GainCertificate:
    """The closed-form certificate of a gain box (frozen gains only).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : GainVariation
        Gain class; only ``frozen`` is covered.

    Returns
    -------
    GainCertificate
        Verdict at the worst vertex, the admissible polytope and the box's delay margin.
    """
    if variation.kind != "frozen":
        raise ValueError(f"the closed form (nuno) covers frozen, scheduled:L and tank gains, not "
                         f"{variation} gains; certify those with the LMIs (method lmi)")
    worst = worst_vertex(box)
    slack = nuno_slack(params, worst, tl_max, tr_max)
    certified = bool(np.all(slack > 0))
    violation = None
    if not certified:
        i = int(np.argmin(slack))
        violation = (f"joint {i + 1} at K_r = {worst[i]:g}, B_r = {worst[box.n_joints + i]:g}: "
                     f"4 B_l B_r - (T_l*+T_r*)^2 K_l K_r = {slack[i]:.6g} <= 0")
    ratios = np.array(box.kr) / np.asarray(params.local_gains.stiffness)[:, None]
    one_ratio = box.n_joints == 1 or bool(np.allclose(ratios, ratios[0, 0]))
    assumptions = ASSUMPTIONS if one_ratio else (*ASSUMPTIONS, RATIO_CAVEAT)
    return GainCertificate(certified, "nuno", str(variation), (tl_max, tr_max),
                           nuno_delay_margin(params, box), box,
                           nuno_polytope(params, box, tl_max, tr_max), True, assumptions,
                           violation, {"slack": slack.tolist()}, plant_record(params))
