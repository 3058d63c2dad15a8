"""The readable integrator: numpy, batched, one Runge–Kutta step at a time.

It states the closed loop the way the paper writes it, using :mod:`teleopkit.model.dynamics`,
:mod:`teleopkit.model.laws` and :class:`teleopkit.delays.history.ChannelHistory`. The compiled
kernel (:mod:`teleopkit.sim.kernel`) must agree with it to rounding error; it is also the "plain
per-step Python loop" of the benchmarks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from teleopkit.delays.history import ChannelHistory
from teleopkit.model.dynamics import coriolis_matrix, mass_matrix
from teleopkit.model.laws import environment_torque, local_torque, operator_torque, remote_torque
from teleopkit.model.params import PlanarArm, TeleoperatorParams
from teleopkit.sim import tableau
from teleopkit.sim.state import StateLayout

if TYPE_CHECKING:
    from teleopkit.sim.scenarios import Scenario

__all__ = ["NumpyIntegrator"]


def _combine(coefficients: np.ndarray, slopes: list[np.ndarray]) -> np.ndarray:
    """``sum_j coefficients[j] slopes[j]`` over the non-zero coefficients, in order."""
    terms = [a * k for a, k in zip(coefficients, slopes, strict=False) if a != 0.0]
    total = terms[0]
    for term in terms[1:]:
        total = total + term
    return total


class NumpyIntegrator:
    """Fixed-step Runge–Kutta (:mod:`teleopkit.sim.tableau`) of the delayed teleoperator, in numpy.

    Parameters
    ----------
    scenario : Scenario
        The batch: its plants and which one each scenario runs.
    state : ndarray, shape (B, 12 n)
        Initial state (:class:`~teleopkit.sim.state.StateLayout`).
    dt : float
        Integration step.
    substeps : int
        Integration steps per control period.
    bound : float
        Largest delay that will be read.
    """

    def __init__(self, scenario: Scenario, state: np.ndarray, dt: float, substeps: int,
                 bound: float) -> None:
        self.scenario = scenario
        self.state = np.array(state, dtype=float)
        self.dt = dt
        self.substeps = substeps
        self.layout = StateLayout(scenario.params.n_joints)
        self.channels = tuple(ChannelHistory(self.layout.channel(self.state, c)[0], dt, bound)
                              for c in (0, 1))

    def advance(self, delays: np.ndarray, qh: np.ndarray, gains: np.ndarray,
                left: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Integrate ``gains.shape[0]`` control periods.

        Parameters
        ----------
        delays : ndarray, shape (R P substeps + 1, B, 2)
            Forward and backward delays (seconds) on the stage grid from the current time
            (``R`` = :data:`~teleopkit.sim.tableau.ROWS_PER_STEP` rows per step).
        qh : ndarray, shape (R P substeps + 1, B, n)
            Operator reference at the same times.
        gains : ndarray, shape (P, B, 2 n)
            Remote gains ``[K_r, B_r]`` held over each control period.
        left : ndarray, shape (P substeps, B, 2), optional
            For delays that jump: their left limits at the end of every step, read by the
            step's last stage (:mod:`teleopkit.delays.jumps`).

        Returns
        -------
        states : ndarray, shape (P, B, 12 n)
            State at the end of each period.
        delayed : ndarray, shape (P, B, 2, n)
            ``q_l(t - T_l)`` and ``theta(t - T_r)`` at the end of each period.
        """
        per_step = tableau.ROWS_PER_STEP
        states, delayed = [], []
        for p, period_gains in enumerate(gains):
            for s in range(self.substeps):
                step = p * self.substeps + s
                row = per_step * step
                window = delays[row:row + per_step + 1]
                if left is not None:
                    window = np.concatenate([window[:-1], left[step][None]])
                self._step(window, qh[row:row + per_step + 1], period_gains)
            row_end = per_step * (p + 1) * self.substeps
            states.append(self.state.copy())
            delayed.append(np.stack(self._delayed(self.state, 0.0, delays[row_end]), axis=1))
        return np.array(states), np.array(delayed)

    def _step(self, delays: np.ndarray, qh: np.ndarray, gains: np.ndarray) -> None:
        slopes: list[np.ndarray] = []
        for coefficients, offset, row in zip(tableau.A, tableau.C, tableau.ROWS, strict=True):
            stage = self.state + self.dt * _combine(coefficients, slopes) if slopes else self.state
            slopes.append(self.derivative(stage, offset, delays[row], qh[row], gains))
        self.state = self.state + self.dt * _combine(tableau.B, slopes)
        for c, channel in enumerate(self.channels):
            channel.record(*self.layout.channel(self.state, c))

    def _delayed(self, x: np.ndarray, offset: float, delays: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
        forward, backward = (channel.read(offset, delays[:, c],
                                          self.layout.channel(x, c))
                             for c, channel in enumerate(self.channels))
        return forward, backward

    def derivative(self, x: np.ndarray, offset: float, delays: np.ndarray, qh: np.ndarray,
                   gains: np.ndarray) -> np.ndarray:
        """Time derivative of the state at ``t_k + offset dt`` (the stage's delayed read-outs).

        Parameters
        ----------
        x : ndarray, shape (B, 12 n)
            Stage state.
        offset : float
            Stage time after the newest stored sample, in steps.
        delays : ndarray, shape (B, 2)
            Forward and backward delays at the stage time.
        qh : ndarray, shape (B, n)
            Operator reference at the stage time.
        gains : ndarray, shape (B, 2 n)
            Remote gains.

        Returns
        -------
        ndarray, shape (B, 12 n)
            The derivative.
        """
        ql_delayed, th_delayed = self._delayed(x, offset, delays)
        if not self.scenario.other_plants:  # no copies of the batch for one plant
            return self._motion(self.scenario.params, x, ql_delayed, th_delayed, qh, gains)
        return self.scenario.per_plant(
            lambda params, lanes: self._motion(params, x[lanes], ql_delayed[lanes],
                                               th_delayed[lanes], qh[lanes], gains[lanes]),
            np.arange(len(x)))

    def _motion(self, p: TeleoperatorParams, x: np.ndarray, ql_delayed: np.ndarray,
                th_delayed: np.ndarray, qh: np.ndarray, gains: np.ndarray) -> np.ndarray:
        """The derivative of scenarios that run the plant ``p``, given their delayed reads."""
        ql, dql, qr, dqr, th, dth = (self.layout.get(x, name)
                                     for name in ("ql", "dql", "qr", "dqr", "theta", "dtheta"))
        tau_l = local_torque(p.local_gains, ql, dql, th_delayed, p.torque_limit)
        tau_r = remote_torque(gains, th, dth, ql_delayed, p.torque_limit)
        tau_h = operator_torque(p.operator, qh, ql, dql)
        tau_e = environment_torque(p.environment, qr, dqr)
        spring = np.array(p.joints.stiffness) * (qr - th)
        ddql = self._acceleration(p.local_arm, ql, dql, tau_h - tau_l)
        ddqr = self._acceleration(p.remote_arm, qr, dqr, -spring - tau_e)
        ddth = (tau_r + spring) / np.array(p.joints.rotor_inertia)
        get = self.layout.get
        return self.layout.pack(len(x), ql=dql, dql=ddql, qr=dqr, dqr=ddqr, theta=dth,
                                dtheta=ddth, int_track=th - ql_delayed, int_damp=th - qr,
                                int_dql2=dql**2, iint_dql2=get(x, "int_dql2"),
                                int_dtheta2=dth**2, iint_dtheta2=get(x, "int_dtheta2"))

    @staticmethod
    def _acceleration(arm: PlanarArm, q: np.ndarray, dq: np.ndarray,
                      torque: np.ndarray) -> np.ndarray:
        coriolis = np.einsum("bij,bj->bi", coriolis_matrix(arm, q, dq), dq)
        return np.linalg.solve(mass_matrix(arm, q), (torque - coriolis)[..., None])[..., 0]
