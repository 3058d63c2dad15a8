"""P+d control laws, the operator and the environment (numpy, batched over leading axes).

Paper eqs. (4)-(5), gains diagonal per joint:

* local: ``tau_l = K_l (q_l - theta_r(t - T_r)) + B_l q_l'``
* remote: ``tau_r = -K_r (theta_r - q_l(t - T_l)) - B_r theta_r'``
* operator: ``tau_h = K_s (q_h - q_l) - K_d q_l'``
* environment: ``tau_e = 0`` in free space, a one-sided spring-damper at a
  :class:`~teleopkit.model.params.Wall`.

Motor torques saturate at ``+- torque_limit``.
"""

from __future__ import annotations

import numpy as np

from teleopkit.model.params import Operator, PDGains, Wall

__all__ = ["environment_torque", "local_torque", "operator_torque", "remote_torque"]


def local_torque(gains: PDGains, q: np.ndarray, dq: np.ndarray, theta_delayed: np.ndarray,
                 limit: float = np.inf) -> np.ndarray:
    """Local P+d torque ``K_l (q_l - theta_r(t - T_r)) + B_l q_l'``, saturated at ``limit``.

    Parameters
    ----------
    gains : PDGains
        Local gains ``K_l, B_l``.
    q, dq : ndarray, shape (..., n)
        Local link angles and velocities.
    theta_delayed : ndarray, shape (..., n)
        Remote motor angles received over the backward channel.
    limit : float
        Torque saturation.

    Returns
    -------
    ndarray, shape (..., n)
        The torque ``tau_l``.
    """
    tau = np.array(gains.stiffness) * (q - theta_delayed) + np.array(gains.damping) * dq
    return np.clip(tau, -limit, limit)


def remote_torque(gains: np.ndarray, theta: np.ndarray, dtheta: np.ndarray,
                  q_delayed: np.ndarray, limit: float = np.inf) -> np.ndarray:
    """Remote P+d torque ``-K_r (theta_r - q_l(t - T_l)) - B_r theta_r'``, saturated at ``limit``.

    Parameters
    ----------
    gains : ndarray, shape (..., 2 n)
        Remote gains as an action vector ``[K_r^1..K_r^n, B_r^1..B_r^n]``.
    theta, dtheta : ndarray, shape (..., n)
        Remote motor angles and velocities.
    q_delayed : ndarray, shape (..., n)
        Local link angles received over the forward channel.
    limit : float
        Torque saturation.

    Returns
    -------
    ndarray, shape (..., n)
        The torque ``tau_r``.
    """
    n = theta.shape[-1]
    tau = -gains[..., :n] * (theta - q_delayed) - gains[..., n:] * dtheta
    return np.clip(tau, -limit, limit)


def operator_torque(operator: Operator, q_ref: np.ndarray, q: np.ndarray,
                    dq: np.ndarray) -> np.ndarray:
    """Operator torque ``K_s (q_h - q_l) - K_d q_l'``.

    Parameters
    ----------
    operator : Operator
        Operator stiffness and damping.
    q_ref : ndarray, shape (..., n)
        Operator's reference ``q_h``.
    q, dq : ndarray, shape (..., n)
        Local link angles and velocities.

    Returns
    -------
    ndarray, shape (..., n)
        The torque ``tau_h``.
    """
    return operator.stiffness * (q_ref - q) - operator.damping * dq


def environment_torque(environment: str | Wall, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Environment torque ``tau_e`` (zero in free space; a one-sided spring-damper at a wall).

    Parameters
    ----------
    environment : {"free"} or Wall
        The environment.
    q, dq : ndarray, shape (..., n)
        Remote link angles and velocities.

    Returns
    -------
    ndarray, shape (..., n)
        The torque ``tau_e`` (it enters the link dynamics as ``-tau_e``).
    """
    if not isinstance(environment, Wall):
        return np.zeros_like(q)
    depth = q - np.array(environment.position)
    push = np.maximum(0.0, environment.stiffness * depth + environment.damping * dq)
    return np.where(depth > 0, push, 0.0)
