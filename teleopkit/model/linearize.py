r"""The teleoperator linearised at rest, as a linear delay system for :mod:`certify`.

Around rest (all velocities zero, operator reference at the origin, no wall contact, no saturation)
the Coriolis terms vanish to first order and the closed loop is, in descriptor form with the state
``x = [q_l, q_l', q_r, q_r', theta, theta']``,

.. math::

    E(c)\, x' = A_0 x + A_l\, x(t - T_l(t)) + A_r\, x(t - T_r(t)),

with ``E = diag(I, M_l, I, M_r, I, J_r)``. The inertia depends on the configuration only through
the cosines ``c_ij = cos(phi_i - phi_j)`` of the relative link angles, and ``E`` is affine in
them, so the vertices ``c_ij = +-1`` span a polytope that contains every configuration. The channel
``A_l`` carries ``q_l(t - T_l)`` into the remote motor, ``A_r`` carries ``theta(t - T_r)`` into the
local arm.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from certify import LinearDelaySystem
from teleopkit.model.dynamics import mass_from_cosines
from teleopkit.model.params import PlanarArm, TeleoperatorParams

if TYPE_CHECKING:
    import control

__all__ = ["inertia_vertices", "linearized_state_space", "linearized_system", "rest_systems"]


def _cosine_patterns(n: int) -> list[np.ndarray]:
    """Matrices of relative-angle cosines at every sign pattern ``cos(phi_i - phi_j) = +-1``."""
    pairs = list(itertools.combinations(range(n), 2))
    patterns = []
    for signs in itertools.product((-1.0, 1.0), repeat=len(pairs)):
        cosines = np.eye(n)
        for (i, j), sign in zip(pairs, signs, strict=True):
            cosines[i, j] = cosines[j, i] = sign
        patterns.append(cosines)
    return patterns


def inertia_vertices(arm: PlanarArm) -> list[np.ndarray]:
    """Inertia matrices at every vertex ``cos(phi_i - phi_j) = +-1`` (positive definite ones).

    Parameters
    ----------
    arm : PlanarArm
        The arm.

    Returns
    -------
    list of ndarray, shape (n, n)
        ``M`` at each sign pattern of the relative-angle cosines; for two links, ``cos q2 = -1``
        and ``cos q2 = +1``.
    """
    masses = (mass_from_cosines(arm, c) for c in _cosine_patterns(arm.n_joints))
    return [m for m in masses if np.linalg.eigvalsh(m).min() > 0]


def rest_systems(params: TeleoperatorParams, action: np.ndarray) -> list[LinearDelaySystem]:
    """The linearisation at every configuration vertex, for one remote gain vector.

    At rest all positions agree (``q_l = q_r = theta``), so both arms sit in the same
    configuration: each vertex uses the same cosines on both arms. The convex hull of the
    returned systems contains the linearisation at every rest configuration.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    action : ndarray, shape (2 n,)
        Remote gains ``[K_r..., B_r...]``.

    Returns
    -------
    list of certify.LinearDelaySystem
        One system per cosine sign pattern at which both inertia matrices are positive
        definite.
    """
    n = params.n_joints
    systems = []
    for cosines in _cosine_patterns(n):
        masses = [mass_from_cosines(arm, cosines) for arm in (params.local_arm, params.remote_arm)]
        if all(np.linalg.eigvalsh(m).min() > 0 for m in masses):
            systems.append(linearized_system(params, action[:n], action[n:], *masses))
    return systems


def _per_joint(name: str, values: np.ndarray | float, n: int) -> np.ndarray:
    """One finite non-negative gain per joint (a scalar is every joint's)."""
    array = np.asarray(values, dtype=float)
    if array.ndim > 1 or array.size not in (1, n):
        raise ValueError(f"{name} needs 1 or {n} values (one per joint), got shape {array.shape}")
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise ValueError(f"{name} must be finite and non-negative, got {array.tolist()}")
    return np.broadcast_to(array.reshape(-1), n).copy() if array.size == 1 else array


def _diag(values: tuple[float, ...] | np.ndarray) -> np.ndarray:
    return np.diag(np.asarray(values, dtype=float))


def linearized_system(params: TeleoperatorParams, kr: np.ndarray | float, br: np.ndarray | float,
                      mass_local: np.ndarray, mass_remote: np.ndarray) -> LinearDelaySystem:
    """The closed loop linearised at rest for given remote gains and inertia matrices.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (local gains, operator spring and damper, joints).
    kr, br : float or ndarray, shape (n,)
        Remote gains ``K_r`` and ``B_r`` (per joint).
    mass_local, mass_remote : ndarray, shape (n, n)
        Inertia matrices of the local and the remote arm (for example from
        :func:`inertia_vertices`).

    Returns
    -------
    certify.LinearDelaySystem
        ``E x' = A0 x + A_l x(t - T_l) + A_r x(t - T_r)`` with ``x = [q_l, q_l', q_r, q_r',
        theta, theta']`` and the delay matrices in the order (forward, backward).
    """
    n = params.n_joints
    eye, zero = np.eye(n), np.zeros((n, n))
    kl, bl = _diag(params.local_gains.stiffness), _diag(params.local_gains.damping)
    ks, kd = params.operator.stiffness * eye, params.operator.damping * eye
    k_r, b_r = np.diag(_per_joint("K_r", kr, n)), np.diag(_per_joint("B_r", br, n))
    s = _diag(params.joints.stiffness)
    a0 = np.block([
        [zero, eye, zero, zero, zero, zero],
        [-(ks + kl), -(kd + bl), zero, zero, zero, zero],
        [zero, zero, zero, eye, zero, zero],
        [zero, zero, -s, zero, s, zero],
        [zero, zero, zero, zero, zero, eye],
        [zero, zero, s, zero, -(k_r + s), -b_r],
    ])
    forward = np.zeros_like(a0)
    forward[5 * n:, :n] = k_r
    backward = np.zeros_like(a0)
    backward[n:2 * n, 4 * n:5 * n] = kl
    e = np.eye(6 * n)
    e[n:2 * n, n:2 * n] = mass_local
    e[3 * n:4 * n, 3 * n:4 * n] = mass_remote
    e[5 * n:, 5 * n:] = _diag(params.joints.rotor_inertia)
    return LinearDelaySystem(a0, (forward, backward), E=e)


def linearized_state_space(params: TeleoperatorParams, kr: np.ndarray | float,
                           br: np.ndarray | float, cos_q: float = 1.0) -> control.StateSpace:
    """The delay-free linearisation as a python-control state space (for Bode and Nyquist).

    Input: the operator reference ``q_h`` (torque ``K_s q_h`` on the local arm); outputs: the
    tracking error ``theta_r - q_l`` and the damping error ``theta_r - q_r``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    kr, br : float or ndarray, shape (n,)
        Remote gains.
    cos_q : float
        Value of every relative-angle cosine at which the inertia is evaluated (in ``[-1, 1]``).

    Returns
    -------
    control.StateSpace
        ``n`` inputs, ``2 n`` outputs, ``6 n`` states.
    """
    import control  # python-control imports matplotlib: only here

    if not -1.0 <= cos_q <= 1.0:
        raise ValueError(f"cos_q must lie in [-1, 1], got {cos_q}")
    n = params.n_joints
    cosines = np.full((n, n), cos_q)
    np.fill_diagonal(cosines, 1.0)
    masses = [mass_from_cosines(arm, cosines) for arm in (params.local_arm, params.remote_arm)]
    system = linearized_system(params, kr, br, *masses)
    assert system.E is not None
    e_inv = np.linalg.inv(system.E)
    a = e_inv @ (system.A0 + sum(system.A))
    b = e_inv[:, n:2 * n] @ (params.operator.stiffness * np.eye(n))
    eye, zero = np.eye(n), np.zeros((n, n))
    c = np.block([[-eye, zero, zero, zero, eye, zero], [zero, zero, -eye, zero, eye, zero]])
    return control.ss(a, b, c, np.zeros((2 * n, n)))

