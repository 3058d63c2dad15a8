"""Whether a step integrates a model stably: its fastest damping against the method's limit.

An explicit Runge–Kutta step is stable on a decaying mode ``exp(-rate t)`` only while
``rate * dt`` stays inside the method's interval on the negative real axis
(:data:`~teleopkit.sim.tableau.REAL_STABILITY_LIMIT`). The fastest such modes of the teleoperator
are dampings:

- the local arm's, ``M_l(q)^{-1} (K_d + B_l)``: the operator's damping and the local controller's,
  largest where the arm's inertia is smallest;
- the remote motor's, ``B_r / J_r``, set by the remote gains.

The arms' springs are oscillating modes: on the local side the operator's spring and the local
controller's stiffness (:func:`local_mode`), on the remote side the elastic joints (``S_r``
between the link and its rotor) and, in contact, a wall's spring-damper on the link
(:func:`remote_mode`). The
method's stability region reaches the imaginary axis only up to ``|lambda| dt = 0.86``, so a
stiff joint or wall needs a short step.

Beyond the limit the run does not fail loudly: it drifts or grows (a stiff wall's contact
overflows to NaN), which a campaign would count as a diverging plant.
:class:`~teleopkit.sim.simulator.Simulator` therefore refuses a step the model's damping or
springs make unstable (:func:`check_step`) and gains whose motor damping would
(:func:`check_motor_damping`).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import replace
from typing import cast

import numpy as np

from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.params import PlanarArm, TeleoperatorParams, Wall
from teleopkit.sim.tableau import REAL_STABILITY_LIMIT, STAGES, A, B
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT

__all__ = ["ACCURATE_FRACTION", "GROWTH_PER_STEP", "accurate_step", "amplification",
           "check_motor_damping", "check_remote_modes", "check_step", "largest_motor_damping",
           "local_damping_rate", "local_mode", "remote_mode"]

ACCURATE_FRACTION = 0.85
"""Fraction of the stability limit up to which a step keeps its accuracy (within 1e-5 rad of a
converged run on the paper's model with a raised local damping; closer to the limit the step is
stable but follows the damped mode less closely, ``docs/performance.rst``)."""

GROWTH_PER_STEP = 1e-6
"""Largest growth per step the method may add to a mode (``|R(lambda dt)| - 1``): below
``|lambda| dt = 0.85`` an undamped mode grows by at most 1.3e-8 per step; 1e-6 is under 2 % over
the paper's 40 s run at 2.5 ms."""

_LEVELS = 720
"""Configurations searched for the local arm's smallest inertia (spread over the joints)."""

_POLYNOMIAL = np.array([1.0, *(B @ np.linalg.matrix_power(A, k) @ np.ones(STAGES)
                               for k in range(STAGES))])
"""Coefficients of the method's stability function ``R(z)``, from ``z^0`` up."""


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
    return _rate(params.local_arm, tuple(damping.tolist()))


@functools.lru_cache(maxsize=4096)
def _rate(arm: PlanarArm, weights: tuple[float, ...]) -> float:
    """Largest eigenvalue of ``W^1/2 M(q)^-1 W^1/2`` over the arm's configurations.

    ``W = diag(weights)``: dampings (a decay rate in 1/s) or stiffnesses (a squared angular
    frequency). Cached: drawn plants share their arms (a bounded cache: ranged arms do not).
    """
    n = arm.n_joints
    if n == 1:
        return float(weights[0] / mass_matrix(arm, np.zeros((1, 1)))[0, 0, 0])
    levels = max(4, round(_LEVELS ** (1.0 / (n - 1))))
    # two links: M is affine in cos q_2, so the rate (convex in it) is largest at q_2 = 0 or pi
    angles = (np.array([0.0, math.pi]) if n == 2
              else np.linspace(-math.pi, math.pi, 2 * (levels // 2) + 1))  # holds 0 and pi
    grid = np.array(list(itertools.product(angles, repeat=n - 1)))
    q = np.concatenate([np.zeros((len(grid), 1)), grid], axis=1)
    scale = np.sqrt(np.asarray(weights))
    inverse = np.linalg.inv(mass_matrix(arm, q))
    rates = np.linalg.eigvalsh(scale[:, None] * inverse * scale[None, :])
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
    """Raise if ``dt`` is too long for the local arm's damping or the remote arm's springs.

    The local arm's damping is :func:`local_damping_rate`; the remote arm's elastic joints and
    wall are checked by :func:`check_remote_modes`.

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
        If ``dt`` times the damping rate exceeds the method's stability limit (the message names
        the limit and :func:`accurate_step`), if ``dt`` cannot integrate the local arm's springs
        (:func:`local_mode`), or as :func:`check_remote_modes`.
    """
    rate = local_damping_rate(params)
    if rate * dt > REAL_STABILITY_LIMIT:
        step = accurate_step(params, control_period)
        raise ValueError(
            f"dt = {dt * 1e3:.4g} ms is beyond the integrator's stability limit for this model: "
            f"the local arm's damping reaches {rate:.4g} 1/s, so dt must be at most "
            f"{REAL_STABILITY_LIMIT / rate * 1e3:.4g} ms; dt = {step * 1e3:.4g} ms "
            f"({round(control_period / step)} steps per control period) also keeps its accuracy "
            f"({_typed(step)})")
    mode = local_mode(params)
    if not _integrates(mode, dt):
        springs = ", ".join(f"{v:g}" for v in params.local_gains.stiffness)
        what = (f"the local arm's springs (operator stiffness K_s = {params.operator.stiffness:g}"
                f" N m/rad, local gains K_l = {springs} N m/rad) are")
        raise ValueError(_beyond(params, what, mode, dt, control_period))
    check_remote_modes(params, dt, control_period)


def local_mode(params: TeleoperatorParams) -> complex:
    """Fastest eigenvalue (1/s) of the local arm's springs and dampers.

    The link, of inertia ``M_l(q)``, is pulled by the operator's spring ``K_s`` and the local
    controller's ``K_l`` (its part on ``q_l``; the delayed remote position enters as an input)
    and damped by ``K_d + B_l``: as a spring-damper ``s^2 + c s + w^2`` with ``w^2`` the largest
    eigenvalue of ``M_l^-1 (K_s + K_l)`` and ``c`` that of ``M_l^-1 (K_d + B_l)`` over the
    configurations (:func:`local_damping_rate`), the estimate :func:`remote_mode` makes.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.

    Returns
    -------
    complex
        ``lambda`` with the largest magnitude.
    """
    springs = np.asarray(params.local_gains.stiffness, dtype=float) + params.operator.stiffness
    square = _rate(params.local_arm, tuple(springs.tolist()))
    return _spring_damper(square, local_damping_rate(params))


def _spring_damper(square: float, rate: float) -> complex:
    """The faster root of ``s^2 + rate s + square``."""
    return complex((-rate - np.sqrt(complex(rate * rate - 4.0 * square))) / 2.0)


def amplification(z: complex | np.ndarray) -> np.ndarray:
    """``|R(z)|``: how much one step of the method scales the mode ``exp(lambda t)``.

    Parameters
    ----------
    z : complex or ndarray
        ``lambda dt``.

    Returns
    -------
    ndarray
        ``|R(z)|``; the step is stable on the mode while it is at most 1
        (:data:`GROWTH_PER_STEP` above it is tolerated).
    """
    return np.abs(np.polyval(_POLYNOMIAL[::-1], np.asarray(z, dtype=complex)))


def remote_mode(params: TeleoperatorParams, contact: bool = False) -> complex:
    """Fastest eigenvalue (1/s) of the remote arm's springs, in free space or wall contact.

    The link, of inertia ``M_r(q)``, is held by the joint springs ``S_r`` to rotors of inertia
    ``J_r`` and, in contact, by the wall's spring ``k`` and damper ``b`` on every joint that has
    a wall. As a spring-damper ``s^2 + c s + w^2`` with ``w^2`` the largest eigenvalue of
    ``M_r^-1 (S_r + k)`` plus the largest ``S_r / J_r`` and ``c`` that of ``M_r^-1 b`` over the
    configurations (:func:`local_damping_rate`'s search): an estimate of the coupled system's
    fastest eigenvalue, exact for one joint in free space and within 1 % of it on the paper's
    arm, free and with a wall at either or both joints.

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    contact : bool
        Whether the link touches every wall it has (ignored in free space).

    Returns
    -------
    complex
        ``lambda`` with the largest magnitude (its real part is the wall's damping, zero in
        free space).
    """
    stiffness = np.asarray(params.joints.stiffness, dtype=float)
    wall = params.environment if isinstance(params.environment, Wall) and contact else None
    touching = np.isfinite(wall.position) if wall is not None else np.zeros(stiffness.size, bool)
    push = touching * (wall.stiffness if wall is not None else 0.0)
    drag = touching * (wall.damping if wall is not None else 0.0)
    rotor = float(np.max(stiffness / np.asarray(params.joints.rotor_inertia)))
    square = _rate(params.remote_arm, tuple((stiffness + push).tolist())) + rotor
    return _spring_damper(square, _rate(params.remote_arm, tuple(drag.tolist())))


def check_remote_modes(params: TeleoperatorParams, dt: float,
                       control_period: float = CONTROL_PERIOD) -> None:
    """Raise if ``dt`` cannot integrate the remote arm's springs (:func:`remote_mode`) stably.

    The joints are checked in free space, then a wall in contact.

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
        One line naming the joints or the wall, the mode, the longest stable step, a step
        dividing the control period and, for a wall, the stiffest wall ``dt`` integrates.
    """
    for contact in (False, True) if isinstance(params.environment, Wall) else (False,):
        mode = remote_mode(params, contact)
        if not _integrates(mode, dt):
            raise ValueError(_too_fast(params, contact, mode, dt, control_period))


def _integrates(mode: complex | np.ndarray, dt: float | np.ndarray) -> np.ndarray:
    """Whether steps ``dt`` integrate ``mode`` stably (to :data:`GROWTH_PER_STEP`)."""
    return amplification(mode * dt) <= 1.0 + GROWTH_PER_STEP


def _too_fast(params: TeleoperatorParams, contact: bool, mode: complex, dt: float,
              control_period: float) -> str:
    """The message of :func:`check_remote_modes` for a mode ``dt`` cannot integrate."""
    if contact:
        wall = cast(Wall, params.environment)
        what = (f"the wall (stiffness {wall.stiffness:g} N m/rad, damping {wall.damping:g} "
                "N m s/rad) on the remote link in contact is")
        stiffest = _floored(_stiffest_wall(params, dt))
        keep = (f", or keep this step with a wall stiffness of at most {stiffest:.4g} N m/rad"
                if stiffest > 0 else ", or keep this step with less wall damping")
    else:
        values = ", ".join(f"{v:g}" for v in params.joints.stiffness)
        what, keep = f"the elastic joints (stiffness {values} N m/rad) are", ""
    return _beyond(params, what, mode, dt, control_period, keep)


def _beyond(params: TeleoperatorParams, what: str, mode: complex, dt: float,
            control_period: float, keep: str = "") -> str:
    """One line: ``what`` has a mode ``dt`` cannot integrate; the step that can."""
    longest = _stable_step(mode)
    step = _dividing(control_period, min(ACCURATE_FRACTION * longest,
                                         accurate_step(params, control_period)))
    return (f"{what} beyond what dt = {dt * 1e3:.4g} ms integrates stably: a mode of "
            f"{abs(mode):.4g} rad/s needs dt at most {longest * 1e3:.4g} ms; dt = "
            f"{step * 1e3:.4g} ms ({round(control_period / step)} steps per control period) "
            f"integrates it stably ({_typed(step)}){keep}")


def _typed(step: float) -> str:
    """``step`` as an option that can be typed back: ``--dt`` and the seconds to 15 digits.

    :func:`~teleopkit.sim.timing.substeps` accepts that as a divisor of the control period; the
    four digits of the figure in ms are too few for its tolerance, 1e-9 of the period.
    """
    digits = np.format_float_positional(step, precision=15, unique=False, fractional=False,
                                        trim="-")
    return f"--dt {digits}"


def _floored(value: float) -> float:
    """``value`` rounded down to four significant digits (what the message may promise)."""
    if value <= 0:
        return 0.0
    unit = 10.0 ** (math.floor(math.log10(value)) - 3)
    return math.floor(value / unit) * unit


def _stable_step(mode: complex) -> float:
    """Longest step below which every step integrates ``mode`` stably (to 0.1 %)."""
    steps = np.linspace(0.0, 4.0, 4001) / abs(mode)  # |R| > 1 well before |z| = 4, any way
    return float(steps[np.argmax(~_integrates(mode, steps)) - 1])  # the step 0 is stable


def _stiffest_wall(params: TeleoperatorParams, dt: float) -> float:
    """Largest wall stiffness (same damping) whose contact ``dt`` integrates stably; 0 if none."""
    wall = cast(Wall, params.environment)

    def stable(stiffness: float) -> bool:
        softer = replace(params, environment=replace(wall, stiffness=stiffness))
        return bool(_integrates(remote_mode(softer, True), dt))

    low, high = 0.0, wall.stiffness
    if not stable(low):
        return 0.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return low


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
                         f"integrates it stably and accurately ({_typed(step)}, "
                         f"{round(control_period / step)} steps per control period)")
