"""The plant's stored energy read off simulated states: one home for every energy of the loop.

The arms' own energies are physics (:func:`~teleopkit.model.dynamics.kinetic_energy`,
:func:`~teleopkit.model.dynamics.elastic_arm_energy`, the same terms the remote energy's one
vectorised expression evaluates from each plant's constants); this module evaluates them on the
state layout of :mod:`teleopkit.sim.state`, adds what the environment and the operator store, and
reads the motor-speed integrals the simulator carries. The storage of the scheduled classes,
the energy tank of their safety layer and the falsification search all take their energies
from here.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from teleopkit.model.dynamics import (
    inertia_coefficients,
    kinetic_energy,
    mass_from_coefficients,
)
from teleopkit.model.params import TeleoperatorParams, Wall
from teleopkit.sim.state import StateLayout

if TYPE_CHECKING:
    from teleopkit.sim.scenarios import Scenario

__all__ = ["BatchRemoteEnergy", "local_energy", "mechanical_energy", "motor_speed_integral",
           "remote_energy"]


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
    return BatchRemoteEnergy.of_plant(params)(state)


@dataclass(frozen=True)
class BatchRemoteEnergy:
    """:func:`remote_energy` of a batch whose scenarios run plants of their own, in one pass.

    The plants' constants are gathered per scenario once (:meth:`of`); evaluating the energy of
    a batch of drawn plants is then one vectorised expression, not a call per plant.

    Parameters
    ----------
    coefficients : ndarray, shape (B, n, n)
        Each scenario's remote :func:`~teleopkit.model.dynamics.inertia_coefficients`.
    rotor_inertia, stiffness : ndarray, shape (B, n)
        Each scenario's rotor inertias and joint stiffnesses.
    wall : ndarray, shape (B, n)
        Each scenario's wall position per joint (``inf``: no wall).
    wall_stiffness : ndarray, shape (B,)
        Each scenario's wall stiffness (0 in free space).
    """

    coefficients: np.ndarray
    rotor_inertia: np.ndarray
    stiffness: np.ndarray
    wall: np.ndarray
    wall_stiffness: np.ndarray

    @classmethod
    def of_plant(cls, params: TeleoperatorParams) -> BatchRemoteEnergy:
        """The constants of one plant, for states of any batch shape.

        Parameters
        ----------
        params : TeleoperatorParams
            The plant.

        Returns
        -------
        BatchRemoteEnergy
            Its energy function (constants without a batch axis).
        """
        wall = params.environment if isinstance(params.environment, Wall) else None
        return cls(inertia_coefficients(params.remote_arm), np.array(params.joints.rotor_inertia),
                   np.array(params.joints.stiffness),
                   np.full(params.n_joints, np.inf) if wall is None else np.array(wall.position),
                   np.array(0.0 if wall is None else wall.stiffness))

    @classmethod
    def of(cls, scenario: Scenario) -> BatchRemoteEnergy:
        """The constants of each scenario's plant.

        Parameters
        ----------
        scenario : Scenario
            The batch.

        Returns
        -------
        BatchRemoteEnergy
            Its energy function.
        """
        plants = [cls.of_plant(params) for params in scenario.plants]
        return cls(*(np.stack([getattr(plant, part.name) for plant in plants])[scenario.plant_of]
                     for part in fields(cls)))

    def __call__(self, state: np.ndarray) -> np.ndarray:
        """``E_r`` of each scenario with its plant.

        Parameters
        ----------
        state : ndarray, shape (B, 12 n), or (..., 12 n) for one plant's constants
            States.

        Returns
        -------
        ndarray, shape (B,) or (...)
            The energies in joules.
        """
        layout = StateLayout.of(state)
        qr, dqr = layout.get(state, "qr"), layout.get(state, "dqr")
        mass = mass_from_coefficients(self.coefficients, qr)
        kinetic = 0.5 * np.einsum("...i,...ij,...j->...", dqr, mass, dqr)
        rotor = 0.5 * np.sum(self.rotor_inertia * layout.get(state, "dtheta") ** 2, axis=-1)
        stretch = qr - layout.get(state, "theta")
        spring = 0.5 * np.sum(self.stiffness * stretch**2, axis=-1)
        depth = np.maximum(0.0, qr - self.wall)
        return kinetic + rotor + spring + 0.5 * self.wall_stiffness * np.sum(depth**2, axis=-1)


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
