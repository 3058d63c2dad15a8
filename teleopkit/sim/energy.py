"""The plant's stored energy read off simulated states: one home for every energy of the loop.

The arms' own energies are physics (:func:`~teleopkit.model.dynamics.kinetic_energy`,
:func:`~teleopkit.model.dynamics.elastic_arm_energy`); this module evaluates them on the state
layout of :mod:`teleopkit.sim.state`, adds what the environment and the operator store, and
reads the motor-speed integrals the simulator carries. The storage of the scheduled classes,
the energy tank of their safety layer and the falsification search all take their energies
from here.
"""

from __future__ import annotations

import numpy as np

from teleopkit.model.dynamics import elastic_arm_energy, kinetic_energy
from teleopkit.model.params import TeleoperatorParams, Wall
from teleopkit.sim.state import StateLayout

__all__ = ["local_energy", "mechanical_energy", "motor_speed_integral", "remote_energy"]


def remote_energy(params: TeleoperatorParams, state: np.ndarray) -> np.ndarray:
    """``E_r``: the remote arm's stored energy (links, rotors, joint springs, a wall's spring).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    state : ndarray, shape (..., 12 n)
        States.

    Returns
    -------
    ndarray, shape (...)
        The energy in joules.
    """
    layout = StateLayout.of(state)
    qr = layout.get(state, "qr")
    energy = elastic_arm_energy(params.remote_arm, params.joints, qr, layout.get(state, "dqr"),
                        layout.get(state, "theta"), layout.get(state, "dtheta"))
    if isinstance(params.environment, Wall):
        depth = np.maximum(0.0, qr - np.array(params.environment.position))
        energy = energy + 0.5 * params.environment.stiffness * np.sum(depth**2, axis=-1)
    return energy


def local_energy(params: TeleoperatorParams, state: np.ndarray) -> np.ndarray:
    """``E_l``: the local arm's kinetic energy and the operator spring's (reference at 0).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    state : ndarray, shape (..., 12 n)
        States.

    Returns
    -------
    ndarray, shape (...)
        The energy in joules. A moving operator reference is an active source: this is the
        energy the operator's spring would store towards the origin.
    """
    layout = StateLayout.of(state)
    ql = layout.get(state, "ql")
    spring = 0.5 * params.operator.stiffness * np.sum(ql**2, axis=-1)
    return kinetic_energy(params.local_arm, ql, layout.get(state, "dql")) + spring


def mechanical_energy(params: TeleoperatorParams, state: np.ndarray) -> np.ndarray:
    """The mechanical energy of both arms: the local arm's kinetic energy plus ``E_r``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    state : ndarray, shape (..., 12 n)
        States.

    Returns
    -------
    ndarray, shape (...)
        The energy in joules (without the operator's spring, whose reference moves).
    """
    layout = StateLayout.of(state)
    local = kinetic_energy(params.local_arm, layout.get(state, "ql"), layout.get(state, "dql"))
    return local + remote_energy(params, state)


def motor_speed_integral(state: np.ndarray) -> np.ndarray:
    """``int_0^t theta_i'^2`` of each motor, carried by the simulator's state.

    Parameters
    ----------
    state : ndarray, shape (..., 12 n)
        States.

    Returns
    -------
    ndarray, shape (..., n)
        The integrals in rad^2 / s.
    """
    return StateLayout.of(state).get(state, "int_dtheta2")
