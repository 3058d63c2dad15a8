r"""The Lyapunov–Krasovskii storage behind the scheduled gain classes, and its value along a run.

Write the local stiffness as ``K_l = k_l S`` with ``k_l = K_l^1`` and ``S = diag(s_i)``, and take
remote stiffness of the same shape, ``K_r(t) = kappa(t) S``. With the energies

.. math::

    E_l = \tfrac12 \dot q_l^\top M_l \dot q_l + E_h, \qquad
    E_r = \tfrac12 \dot q_r^\top M_r \dot q_r + \tfrac12 \dot\theta^\top J \dot\theta
          + \tfrac12 (q_r - \theta)^\top S_r (q_r - \theta) + E_e

(``E_h``, ``E_e``: what the passive operator and environment store) the storage is

.. math::

    V = \frac{E_l}{k_l} + \frac{E_r}{\kappa} + \tfrac12 |q_l - \theta|_S^2
        + \sum_i s_i \Big[ \frac{1}{2 x_i} \int_{-T_r^*}^0 \!\! \int_{t+s}^t \dot\theta_i^2
        + \frac{x_i}{2} \int_{-T_l^*}^0 \!\! \int_{t+s}^t \dot q_{l,i}^2 \Big]

with fixed weights ``x_i = 2 rho_l,i / (T_l* + T_r*)``, ``rho_l,i = B_l^i / K_l^i``. Along the
nonlinear closed loop, for any delays ``0 <= T_l(t) <= T_l*``, ``0 <= T_r(t) <= T_r*`` and gains
held between samples, the coupling terms combine into the derivative of ``|q_l - theta|_S^2 / 2``
and the delayed parts are bounded by Young's and Jensen's inequalities, so between samples

.. math::

    \dot V \le -\sum_i \Big( \frac{B_r^i}{\kappa} - s_i \rho_i \Big) \dot\theta_i^2, \qquad
    \rho_i = \frac{(T_l^* + T_r^*)^2}{4 \rho_{l,i}},

which is non-positive in the cone ``B_r^i >= rho_i K_r^i`` (per joint, the closed form of Nuño et
al.). ``B_r`` enters only there, so it may switch arbitrarily fast inside the cone. At a sample
where ``kappa`` changes from ``kappa_-`` to ``kappa_+``, ``V`` jumps by
``E_r (1/kappa_+ - 1/kappa_-)``: down when ``kappa`` rises, up by at most the factor
``kappa_- / kappa_+`` when it falls. Hence ``V(t) <= exp(L) V(0)`` for a log budget ``L`` of
falls, and ``V + tank`` never rises when an energy tank pays each fall exactly.

The double integrals are exact at every sample: with ``I(t) = int_0^t v^2`` and
``K(t) = int_0^t I`` (integrated by the simulator, :mod:`teleopkit.sim.state`),
``int_{-T}^0 int_{t+s}^t v^2 = T I(t) - K(t) + K(t - T)``, and ``K(t - T)`` is interpolated
between samples by cubic Hermite polynomials (``K' = I``), exact on the grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from teleopkit.certification.delay_bounds import check_delay_bounds
from teleopkit.delays.history import hermite
from teleopkit.model.params import TeleoperatorParams
from teleopkit.sim.energy import local_energy, remote_energy
from teleopkit.sim.state import StateLayout
from teleopkit.sim.trajectory import Trajectory

__all__ = ["ScheduledStorage", "double_integral"]


@dataclass(frozen=True)
class ScheduledStorage:
    """The storage of the scheduled classes for one plant and delay bounds.

    Parameters
    ----------
    shape : tuple of float
        ``s_i = K_l^i / K_l^1``: the shape every remote stiffness vector must have.
    normaliser : float
        ``k_l = K_l^1``.
    weights : tuple of float
        ``x_i = 2 rho_l,i / (T_l* + T_r*)``.
    cone : tuple of float
        ``rho_i``: the damping cone is ``B_r^i >= rho_i K_r^i``.
    tl_max, tr_max : float
        Delay bounds ``T_l*, T_r*`` in seconds.
    """

    shape: tuple[float, ...]
    normaliser: float
    weights: tuple[float, ...]
    cone: tuple[float, ...]
    tl_max: float
    tr_max: float

    @classmethod
    def from_details(cls, details: dict) -> ScheduledStorage:
        """The storage a certificate records (``details["storage"]``, lists read from JSON).

        Parameters
        ----------
        details : dict
            The fields of the storage.

        Returns
        -------
        ScheduledStorage
            The storage.
        """
        fields: dict[str, Any] = {
            key: tuple(value) if isinstance(value, list | tuple) else float(value)
            for key, value in details.items()}
        return cls(**fields)

    @classmethod
    def for_plant(cls, params: TeleoperatorParams, tl_max: float,
                  tr_max: float) -> ScheduledStorage:
        """The storage of ``params`` for the delay bounds ``(T_l*, T_r*)``.

        Parameters
        ----------
        params : TeleoperatorParams
            Teleoperator (its local gains must be positive).
        tl_max, tr_max : float
            Delay bounds in seconds.

        Returns
        -------
        ScheduledStorage
            Shape, weights and cone.

        Raises
        ------
        ValueError
            If a local gain is zero (no storage of this form exists then).
        """
        tl_max, tr_max = check_delay_bounds(tl_max, tr_max)
        kl = np.array(params.local_gains.stiffness)
        bl = np.array(params.local_gains.damping)
        if np.any(kl <= 0) or np.any(bl <= 0):
            raise ValueError("the scheduled classes need positive local gains K_l and B_l, got "
                             f"K_l = {kl.tolist()}, B_l = {bl.tolist()}")
        ratio = bl / kl
        total = tl_max + tr_max
        return cls(tuple((kl / kl[0]).tolist()), float(kl[0]), tuple((2 * ratio / total).tolist()),
                   tuple((total**2 / (4 * ratio)).tolist()), tl_max, tr_max)

    def kappa(self, gains: np.ndarray) -> np.ndarray:
        """The scheduled variable ``kappa = K_r^1 / s_1`` of remote gain vectors.

        Parameters
        ----------
        gains : ndarray, shape (..., 2 n)
            ``[K_r..., B_r...]``.

        Returns
        -------
        ndarray, shape (...)
            ``kappa``.
        """
        return np.asarray(gains)[..., 0] / self.shape[0]

    def value(self, params: TeleoperatorParams, trajectory: Trajectory) -> np.ndarray:
        """``V`` at every recorded time, just after the sample (with the next period's gains).

        Parameters
        ----------
        params : TeleoperatorParams
            The teleoperator simulated.
        trajectory : Trajectory
            A run from ``t = 0`` (recorded every control period).

        Returns
        -------
        ndarray, shape (P, B)
            The storage. Along a run of the class with the operator holding the origin (the
            passive case), it does not rise between samples, falls or stays at a rise of
            ``kappa`` and rises by at most ``kappa_- / kappa_+`` at a fall.

        Notes
        -----
        The operator's stored energy is taken as that of its spring towards the origin: a moving
        reference is an active source, and ``V`` may then rise by the work it does.
        """
        layout = StateLayout.of(trajectory.state)
        state = trajectory.state
        following = np.concatenate([trajectory.gains[1:], trajectory.gains[-1:]])
        shape = np.array(self.shape)
        stretch = layout.get(state, "ql") - layout.get(state, "theta")
        weights = np.array(self.weights)
        delayed = (double_integral(trajectory.t, layout.get(state, "int_dtheta2"),
                                   layout.get(state, "iint_dtheta2"), self.tr_max) / (2 * weights)
                   + double_integral(trajectory.t, layout.get(state, "int_dql2"),
                                     layout.get(state, "iint_dql2"), self.tl_max) * weights / 2)
        return (local_energy(params, state) / self.normaliser
                + remote_energy(params, state) / self.kappa(following)
                + 0.5 * np.sum(shape * stretch**2, axis=-1) + np.sum(shape * delayed, axis=-1))


def double_integral(t: np.ndarray, single: np.ndarray, double: np.ndarray,
                    window: float) -> np.ndarray:
    """``int_{-T}^0 int_{t+s}^t v^2`` at each sample from ``I = int_0^t v^2`` and ``K = int_0^t I``.

    Parameters
    ----------
    t : ndarray, shape (P,)
        Sample times from ``t = 0``, increasing (the signal ``v`` is zero before 0).
    single, double : ndarray, shape (P, ...)
        ``I`` and ``K`` at the samples.
    window : float
        ``T`` in seconds.

    Returns
    -------
    ndarray, shape (P, ...)
        ``T I(t) - K(t) + K(t - T)``, with ``K(t - T)`` by cubic Hermite interpolation
        (``K' = I``) between the samples around ``t - T`` (0 before ``t = 0``).
    """
    t = np.asarray(t, dtype=float)
    start = t - window
    right = np.clip(np.searchsorted(t, start, side="right"), 1, len(t) - 1)
    left = right - 1
    span = t[right] - t[left]
    u = np.clip((start - t[left]) / span, 0.0, 1.0).reshape(-1, *[1] * (single.ndim - 1))
    past = hermite(double[left], single[left], double[right], single[right],
                   span.reshape(u.shape), u)
    past = np.where((start <= t[0]).reshape(u.shape), 0.0, past)
    return window * single - double + past
