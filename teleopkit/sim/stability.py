"""Whether a step integrates a model stably: its fastest damping against the method's limit.

An explicit Runge–Kutta step is stable on a decaying mode ``exp(-rate t)`` only while
``rate * dt`` stays inside the method's interval on the negative real axis
(:data:`~teleopkit.sim.tableau.REAL_STABILITY_LIMIT`). The fastest such modes of the teleoperator
are dampings:

- the local arm's, ``M_l(q)^{-1} (K_d + B_l)``: the operator's damping and the local controller's,
  largest where the arm's inertia is smallest;
- the remote motor's, ``B_r / J_r``, set by the remote gains.

Beyond the limit the run does not fail loudly: it drifts or grows, which a campaign would count
as a diverging plant. :class:`~teleopkit.sim.simulator.Simulator` therefore refuses a step the
model's damping makes unstable (:func:`check_step`) and gains whose motor damping would
(:func:`check_motor_damping`).
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.params import PlanarArm, TeleoperatorParams
from teleopkit.sim.tableau import REAL_STABILITY_LIMIT
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT

__all__ = ["ACCURATE_FRACTION", "accurate_step", "check_motor_damping", "check_step",
           "largest_motor_damping", "local_damping_rate"]

ACCURATE_FRACTION = 0.85
"""Fraction of the stability limit up to which a step keeps its accuracy (within 1e-5 rad of a
converged run on the paper's model with a raised local damping; closer to the limit the step is
stable but follows the damped mode less closely, ``docs/performance.rst``)."""

_LEVELS = 720
"""Configurations searched for the local arm's smallest inertia (spread over the joints)."""


def local_damping_rate(params: TeleoperatorParams) -> float:
    """Fastest decay rate (1/s) of the local arm's damping over its configurations.

    The largest eigenvalue of ``M_l(q)^{-1} diag(K_d + B_l)`` over a grid of the relative joint
    angles (``M_l`` does not depend on the first). For two links the grid holds ``q_2 = 0`` and
    ``q_2 = pi``, where ``M_l`` is extreme (it is affine in ``cos q_2``), so the value is exact; for
    more links it is the largest over about 720 configurations, an estimate.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.

    Returns
    -------
    float
        The rate in 1/s.
    """
    damping = np.asarray(params.local_gains.damping, dtype=float) + params.operator.damping
    return _damping_rate(params.local_arm, tuple(damping.tolist()))


@functools.cache
def _damping_rate(arm: PlanarArm, damping: tuple[float, ...]) -> float:
    """:func:`local_damping_rate` of the local side (cached: drawn plants share it)."""
    n = arm.n_joints
    if n == 1:
        return float(damping[0] / mass_matrix(arm, np.zeros((1, 1)))[0, 0, 0])
    levels = max(4, round(_LEVELS ** (1.0 / (n - 1))))
    angles = np.linspace(-math.pi, math.pi, 2 * (levels // 2) + 1)  # holds 0 and pi
    grid = np.array(list(itertools.product(angles, repeat=n - 1)))
    q = np.concatenate([np.zeros((len(grid), 1)), grid], axis=1)
    scale = np.sqrt(np.asarray(damping))
    inverse = np.linalg.inv(mass_matrix(arm, q))
    rates = np.linalg.eigvalsh(scale[:, None] * inverse * scale[None, :])  # D^1/2 M^-1 D^1/2
    return float(rates.max())


def largest_motor_damping(params: TeleoperatorParams, dt: float) -> float:
    """Largest remote damping gain ``B_r`` the step ``dt`` integrates stably on every joint.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    dt : float
        Integration step in seconds.

    Returns
    -------
    float
        ``REAL_STABILITY_LIMIT / dt`` times the smallest rotor inertia ``J_r``.
    """
    return REAL_STABILITY_LIMIT / dt * min(params.joints.rotor_inertia)


def accurate_step(params: TeleoperatorParams, control_period: float = CONTROL_PERIOD) -> float:
    """Longest step that divides ``control_period`` and keeps the accuracy on ``params``.

    That is, within :data:`ACCURATE_FRACTION` of the stability limit for the local arm's damping
    (:func:`local_damping_rate`), and no longer than the default step
    (:data:`~teleopkit.sim.timing.DEFAULT_DT`): a longer one follows a strongly damped remote
    motor less closely (at 3.33 ms, ``B_r = 120``: 1.7e-5 rad over 20 s for the methods stable
    there). The remote motors' stability depends on the gains and is checked by
    :func:`check_motor_damping`.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    control_period : float
        Gain hold period in seconds.

    Returns
    -------
    float
        ``control_period / N`` for the smallest such whole ``N``.

    Examples
    --------
    >>> from teleopkit.model.params import paper_setup
    >>> round(accurate_step(paper_setup()) * 1e3, 6)  # ms: the default step
    2.5
    """
    return _dividing(control_period, min(
        ACCURATE_FRACTION * REAL_STABILITY_LIMIT / local_damping_rate(params), DEFAULT_DT))


def _dividing(control_period: float, longest: float) -> float:
    """The longest step that divides ``control_period`` and is at most ``longest``."""
    return control_period / math.ceil(control_period / longest - 1e-9)


def check_step(params: TeleoperatorParams, dt: float,
               control_period: float = CONTROL_PERIOD) -> None:
    """Raise if ``dt`` is too long for the local arm's damping (:func:`local_damping_rate`).

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    dt : float
        Integration step in seconds.
    control_period : float
        Gain hold period in seconds (the message proposes a step that divides it).

    Raises
    ------
    ValueError
        If ``dt`` times the damping rate exceeds the method's stability limit; the message names
        the limit and :func:`accurate_step`.
    """
    rate = local_damping_rate(params)
    if rate * dt > REAL_STABILITY_LIMIT:
        step = accurate_step(params, control_period)
        raise ValueError(
            f"dt = {dt * 1e3:.4g} ms is beyond the integrator's stability limit for this model: "
            f"the local arm's damping reaches {rate:.4g} 1/s, so dt must be at most "
            f"{REAL_STABILITY_LIMIT / rate * 1e3:.4g} ms; dt = {step * 1e3:.4g} ms "
            f"({round(control_period / step)} steps per control period) also keeps its accuracy")


def check_motor_damping(params: TeleoperatorParams, dt: float, damping: float,
                        name: str = "B_r", control_period: float = CONTROL_PERIOD) -> None:
    """Raise if the remote damping gain ``damping`` is too large for ``dt`` on some motor.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    dt : float
        Integration step in seconds.
    damping : float
        The largest remote damping gain ``B_r`` to be applied.
    name : str
        What the message calls the gain.
    control_period : float
        Gain hold period in seconds (the message proposes a step that divides it).

    Raises
    ------
    ValueError
        If ``damping`` exceeds :func:`largest_motor_damping`; the message proposes the longest
        step dividing the control period that keeps both dampings within
        :data:`ACCURATE_FRACTION` of the limit.
    """
    largest = largest_motor_damping(params, dt)
    if damping > largest:
        accurate = ACCURATE_FRACTION * largest_motor_damping(params, 1.0) / damping
        step = _dividing(control_period, min(accurate, accurate_step(params, control_period)))
        raise ValueError(f"{name} = {damping:.4g} is beyond what dt = {dt * 1e3:.4g} ms integrates "
                         f"stably on its motor (at most {largest:.4g}); dt = {step * 1e3:.4g} ms "
                         f"integrates it stably and accurately")
