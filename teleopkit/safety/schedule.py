r"""The scheduled gain classes at run time: a coupled projection that keeps a budget or a tank.

The set of a control step is

.. math::

    \{ a : K_r^i = \kappa s_i,\ \kappa \in [\max(\kappa_{min}, \kappa_{floor}), \kappa_{max}],\
    B_{lo}^i \le B_r^i \le B_{hi}^i,\ B_r^i \ge \rho_i s_i \kappa + \beta_i \},

the certificate's common-shape polytope with a floor on ``kappa`` from the run-time state:
``kappa_- exp(-budget)`` for ``scheduled:L`` (a fall spends ``ln(kappa_- / kappa_+)``), and
``1 / (1 / kappa_- + tank / E_r)`` for ``tank`` (a fall costs the storage it adds,
``E_r (1 / kappa_+ - 1 / kappa_-)``, with ``E_r`` the remote energy measured at the sample).

The projection is exact without an iterative solver. For a fixed ``kappa`` the best damping is
``B_r^i = clip(raw, max(B_lo^i, rho_i s_i kappa + beta_i), B_hi^i)``, which leaves a convex
piecewise-quadratic function of ``kappa`` alone. Its derivative is piecewise linear and
increasing, with a kink where a cone becomes active (``rho_i s_i kappa + beta_i = max(raw_i,
B_lo^i)``); the minimiser is found by walking the sorted kinks, and is then clipped into the
step's interval of ``kappa``. No distances are compared, so near-ties cannot pick a wrong point.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.safety.layer import FLAGS, Projection, SafetyLayer, kkt_polish

__all__ = ["BUDGET", "TANK", "ScheduleLayer", "project_scheduled"]

BUDGET, TANK = 0, 1
"""Run-time modes of the kernel: a log budget of falls, or an energy tank."""

_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "_nrt": False}


@njit(forceinline=True, **_OPTIONS)
def _minimiser(raw: np.ndarray, shape: np.ndarray, rho: np.ndarray, beta: np.ndarray,
               b_lo: np.ndarray, kinks: np.ndarray, order: np.ndarray) -> float:
    """The unconstrained minimiser over ``kappa`` of the cost with the best damping."""
    n = shape.size
    for i in range(n):
        slope = rho[i] * shape[i]
        kinks[i] = (max(raw[n + i], b_lo[i]) - beta[i]) / slope
        order[i] = i
    for i in range(1, n):  # insertion sort of the kinks (n is the number of joints)
        j = i
        while j > 0 and kinks[order[j - 1]] > kinks[order[j]]:
            order[j - 1], order[j] = order[j], order[j - 1]
            j -= 1
    num, den = 0.0, 0.0
    for i in range(n):
        num += shape[i] * raw[i]
        den += shape[i] * shape[i]
    start = -math.inf
    for j in range(n + 1):
        end = kinks[order[j]] if j < n else math.inf
        root = num / den
        if root <= end:
            return max(root, start)
        i = order[j]
        slope = rho[i] * shape[i]
        num += slope * (raw[n + i] - beta[i])
        den += slope * slope
        start = end
    return start  # not reached: the last piece ends at infinity


@njit(**_OPTIONS)
def project_scheduled(raw: np.ndarray, out: np.ndarray, flags: np.ndarray, distance: np.ndarray,
                      floor: np.ndarray, active: np.ndarray, tol: float, shape: np.ndarray,
                      rho: np.ndarray, beta: np.ndarray,
                      b_lo: np.ndarray, b_hi: np.ndarray, kappa_lo: float, kappa_hi: float,
                      prev: np.ndarray, level: np.ndarray, energy: np.ndarray, mode: int,
                      refill: float, centre: np.ndarray, kinks: np.ndarray,
                      order: np.ndarray) -> None:
    """Project a batch of raw actions onto the step's set and update the run-time state.

    Parameters
    ----------
    raw : ndarray, shape (B, 2 n)
        Raw actions (NaN and inf allowed: the previous action is applied again, or ``centre``
        at the first step).
    out : ndarray, shape (B, 2 n)
        Receives the applied actions.
    flags : ndarray of int, shape (B,)
        Receives 1 where the raw action was not finite, else 0.
    distance : ndarray, shape (B,)
        Receives ``||out - raw||`` (``inf`` for a non-finite raw action).
    floor : ndarray, shape (B,)
        Receives the floor of ``kappa`` in force at this step.
    active : ndarray of bool, shape (B, 3 + 3 n)
        Receives which constraints hold with equality (within ``tol`` relative): the floor, the
        two ends of ``kappa``'s interval, the damping box's lower and upper ends, the cones.
    tol : float
        Relative tolerance of the report.
    shape, rho, beta, b_lo, b_hi : ndarray, shape (n,)
        The common shape, the cone ``B_r^i >= rho_i s_i kappa + beta_i`` and the damping box.
    kappa_lo, kappa_hi : float
        The static interval of ``kappa``.
    prev : ndarray, shape (B, 2 n)
        The action applied at the previous step (NaN at the first); updated to ``out``.
    level : ndarray, shape (B,)
        Budget left (mode :data:`BUDGET`) or tank level (mode :data:`TANK`); updated.
    energy : ndarray, shape (B,)
        The remote energy ``E_r`` measured at this sample (tank mode).
    mode : int
        :data:`BUDGET` or :data:`TANK`.
    refill : float
        Fraction of the storage released by a rise of ``kappa`` that refills the tank.
    centre : ndarray, shape (2 n,)
        An interior action, applied when nothing finite is available.
    kinks : ndarray, shape (n,)
        Scratch.
    order : ndarray of int, shape (n,)
        Scratch.
    """
    n = shape.size
    for b in range(raw.shape[0]):
        previous = prev[b, 0] / shape[0]
        has_prev = math.isfinite(previous)
        low = kappa_lo
        if has_prev:
            if mode == BUDGET:
                low = max(low, previous * math.exp(-level[b]))
            elif energy[b] > 0.0:
                low = max(low, 1.0 / (1.0 / previous + level[b] / energy[b]))
            low = min(low, previous)  # the previous kappa is always allowed again
        floor[b] = low
        finite = True
        for c in range(2 * n):
            if not math.isfinite(raw[b, c]):
                finite = False
        if finite:
            kappa = min(max(_minimiser(raw[b], shape, rho, beta, b_lo, kinks, order), low),
                        kappa_hi)
            for i in range(n):
                cone = rho[i] * shape[i] * kappa + beta[i]
                out[b, i] = kappa * shape[i]
                out[b, n + i] = min(max(raw[b, n + i], max(b_lo[i], cone)), b_hi[i])
            total = 0.0
            for c in range(2 * n):
                total += (out[b, c] - raw[b, c]) ** 2
            flags[b], distance[b] = 0, math.sqrt(total)
        else:
            kappa = previous if has_prev else centre[0] / shape[0]
            for c in range(2 * n):
                out[b, c] = prev[b, c] if has_prev else centre[c]
            flags[b], distance[b] = 1, math.inf
        if has_prev and kappa != previous:
            if mode == BUDGET:
                level[b] = max(0.0, level[b] - max(0.0, math.log(previous / kappa)))
            else:
                change = energy[b] * (1.0 / kappa - 1.0 / previous)
                level[b] = max(0.0, level[b] - change) if change > 0 else level[b] - refill * change
        near = tol * (1.0 + abs(kappa))
        active[b, 0] = abs(kappa - low) <= near
        active[b, 1] = abs(kappa - kappa_lo) <= near
        active[b, 2] = abs(kappa - kappa_hi) <= near
        for i in range(n):
            near = tol * (1.0 + abs(out[b, n + i]))
            active[b, 3 + i] = abs(out[b, n + i] - b_lo[i]) <= near
            active[b, 3 + n + i] = abs(out[b, n + i] - b_hi[i]) <= near
            active[b, 3 + 2 * n + i] = abs(out[b, n + i] - rho[i] * shape[i] * kappa
                                           - beta[i]) <= near
        for c in range(2 * n):
            prev[b, c] = out[b, c]


class ScheduleLayer(SafetyLayer):
    """The safety layer of a scheduled class: the step's coupled set and its run-time state.

    Every :meth:`step` is one control step of an episode: it projects onto the set of that step
    (the common shape, the box, the cone and the floor on ``kappa``) and spends the budget or
    the tank. :meth:`reset` starts an episode; with a tank, :meth:`observe` takes the measured
    remote energy and motor speeds at every sample. Build it with
    :func:`~teleopkit.safety.factory.layer_for`.

    Parameters
    ----------
    certificate : GainCertificate
        A ``scheduled:L`` or ``tank`` certificate whose set is certified.
    tol : float
        Tolerance of the active-constraint report.
    """

    def __init__(self, certificate: GainCertificate, tol: float = 1e-9) -> None:
        allowed = certificate.scheduled_set
        if allowed is None:
            raise ValueError(f"a schedule layer needs a scheduled:L or tank certificate, not "
                             f"{certificate.gain_variation}")
        if allowed.is_empty:
            raise ValueError("the certificate's common-shape set is empty")
        if not np.all(certificate.polytope.contains(allowed.corners())):
            raise ValueError("the certificate's scheduled set is not inside its polytope")
        self.certificate = certificate
        self.polytope = certificate.polytope
        self.scheduled = allowed
        self.tol = float(tol)
        self._set = (*allowed.arrays(), allowed.kappa_low, allowed.kappa_high)
        self._mode = TANK if allowed.rule == "tank" else BUDGET
        self._centre = allowed.centre()
        n = allowed.n_joints
        self._scratch = (np.empty(n), np.empty(n, dtype=np.int64))
        self._labels = ("kappa >= floor (budget or tank)", "kappa >= min", "kappa <= max",
                        *(f"B_r{i + 1} >= min" for i in range(n)),
                        *(f"B_r{i + 1} <= max" for i in range(n)),
                        *(f"cone joint {i + 1}: B_r{i + 1} >= rho K_r{i + 1}"
                          for i in range(n)))
        self.reset()

    @property
    def measures_energy(self) -> bool:  # type: ignore[override]
        """Whether the layer is paid from a tank (then :meth:`observe` needs the energy)."""
        return self._mode == TANK

    @property
    def admissible_set(self) -> ScheduledSet:
        """The class's static set (the step's set adds the floor on ``kappa``)."""
        return self.scheduled

    @property
    def labels(self) -> tuple[str, ...]:
        """The constraints of :attr:`Projection.active`: floor, interval, damping box, cones."""
        return self._labels

    @property
    def fallback_action(self) -> np.ndarray:
        """The interior action applied at a first step whose raw action is not finite."""
        return self._centre.copy()

    def reset(self) -> None:
        """Start an episode: full budget or initial tank, no previous action."""
        self._prev: np.ndarray | None = None
        self._level = np.zeros(0)
        self._energy = np.zeros(0)
        self._integral = np.zeros((0, self.scheduled.n_joints))
        self.last_floor = np.zeros(0)

    def _start(self, batch: int) -> None:
        self._prev = np.full((batch, self.dimension), np.nan)
        self._level = np.full(batch, self.scheduled.initial)
        if self._energy.shape != (batch,):
            self._energy = np.zeros(batch)
            self._integral = np.zeros((batch, self.scheduled.n_joints))

    def observe(self, energy: np.ndarray, motor_speed_integral: np.ndarray) -> None:
        """Take the measured remote energy and refill the tank with the proven dissipation.

        Parameters
        ----------
        energy : ndarray, shape (B,)
            The remote arm's stored energy ``E_r`` in joules at the sample.
        motor_speed_integral : ndarray, shape (B, n)
            ``int_0^t theta_i'^2`` of each motor; its increase since the last sample, weighted
            by the proven dissipation rates of the gains applied over it, refills the tank.
        """
        if self._mode != TANK:
            return
        integral = np.asarray(motor_speed_integral, dtype=float)
        if self._prev is not None and self._prev.shape[0] == integral.shape[0]:
            applied = np.all(np.isfinite(self._prev), axis=1)
            rates = self.scheduled.dissipation_rates(np.nan_to_num(self._prev, nan=1.0))
            gained = np.sum(rates * (integral - self._integral), axis=1)
            self._level = self._level + np.where(applied, self.scheduled.refill * gained, 0.0)
        self._energy = np.asarray(energy, dtype=float)
        self._integral = integral

    def run_time_state(self, batch: int) -> np.ndarray:
        """What the step's set depends on, beside the plant: the agent observes it.

        Parameters
        ----------
        batch : int
            Number of scenarios.

        Returns
        -------
        ndarray, shape (B, 2) or (B, 3)
            The budget left or the tank level, the previous ``kappa`` (``kappa_min`` before the
            first step: then no floor applies) and, with a tank, the measured remote energy
            ``E_r``: the step's floor follows from them.
        """
        prev = self._prev if self._prev is not None and self._prev.shape[0] == batch else None
        level = self._level if prev is not None else np.full(batch, self.scheduled.initial)
        kappa = np.full(batch, self.scheduled.kappa_low)
        if prev is not None:
            kappa = np.where(np.isfinite(prev[:, 0]), self.scheduled.kappa(prev), kappa)
        columns = [level, kappa]
        if self._mode == TANK:
            columns.append(self._energy if self._energy.shape == (batch,) else np.zeros(batch))
        return np.column_stack(columns)

    def contains(self, actions: np.ndarray) -> np.ndarray:
        """Whether actions lie in the class: the static set, with the budget or tank not overdrawn.

        Parameters
        ----------
        actions : ndarray, shape (..., 2 n)
            Gain vectors (for a batch of the current episode, its run-time state is checked
            too).

        Returns
        -------
        ndarray of bool, shape (...)
            Membership of each action.
        """
        inside = self.polytope.contains(actions)
        if inside.shape == self._level.shape:
            inside = inside & (self._level >= -self.tol * (1.0 + abs(self.scheduled.initial)))
        return inside

    def project_set(self, raw: np.ndarray) -> np.ndarray:
        """The nearest points of the static set (the first step's set), leaving the state alone.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions (finite).

        Returns
        -------
        ndarray, the shape of ``raw``
            Their projections: common shape, box and cone; constant gains of the class.
        """
        raw = np.asarray(raw, dtype=float)
        flat = np.ascontiguousarray(np.atleast_2d(raw))
        count = flat.shape[0]
        out = np.empty_like(flat)
        project_scheduled(flat, out, np.empty(count, dtype=np.int64), np.empty(count),
                          np.empty(count), np.empty((count, len(self.labels)), dtype=np.bool_),
                          self.tol, *self._set, np.full_like(flat, np.nan),
                          np.full(count, self.scheduled.initial), np.zeros(count), self._mode,
                          self.scheduled.refill, self._centre, *self._scratch)
        return out.reshape(raw.shape)

    def step(self, raw: np.ndarray) -> Projection:
        """One control step: project onto the step's set and spend the budget or the tank.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions; NaN and inf are allowed (the previous action is applied again, or the
            centre of the set at the first step).

        Returns
        -------
        Projection
            Applied actions, distances, active constraints (:attr:`labels`), flags and the
            budget or tank left (scalars for one action).

        Raises
        ------
        ValueError
            On a batch size other than the episode's (call :meth:`reset` to start another).
        """
        raw = np.asarray(raw, dtype=np.float64)
        single = raw.ndim == 1
        flat = np.atleast_2d(raw)
        shape = (flat.shape[0], self.dimension)
        flat = self._actions(flat, shape, "raw actions")
        if self._prev is None:
            self._start(shape[0])
        assert self._prev is not None
        if self._prev.shape != shape:
            raise ValueError(f"the episode has {self._prev.shape[0]} scenarios, got "
                             f"{shape[0]}; call reset() to start another")
        out = np.empty(shape)
        flags = np.empty(shape[0], dtype=np.int64)
        distance = np.empty(shape[0])
        self.last_floor = np.empty(shape[0])
        active = np.empty((shape[0], len(self.labels)), dtype=np.bool_)
        project_scheduled(flat, out, flags, distance, self.last_floor, active, self.tol,
                          *self._set, self._prev, self._level, self._energy, self._mode,
                          self.scheduled.refill, self._centre, *self._scratch)
        if single:
            return Projection(out[0], float(distance[0]), active[0], np.zeros(self.dimension,
                              dtype=bool), FLAGS[flags[0]], float(self._level[0]))
        return Projection(out, distance, active, np.zeros(shape, dtype=bool), flags,
                          self._level.copy())

    def project_qp(self, raw: np.ndarray, floor: float = 0.0) -> np.ndarray:
        """Solve the step's projection QP with cvxpy and Clarabel (reference for the kernel).

        Parameters
        ----------
        raw : ndarray, shape (2 n,)
            Raw action (finite).
        floor : float
            The step's floor on ``kappa`` (for example ``last_floor`` of a step).

        Returns
        -------
        ndarray, shape (2 n,)
            The projection onto the certificate's polytope with ``kappa >= floor``.
        """
        import cvxpy as cp

        raw = self._actions(raw, (self.dimension,), "raw action")
        floor_row = np.zeros(self.dimension)
        floor_row[0] = -1.0
        g = np.vstack([self.polytope.G, floor_row])
        h = np.append(self.polytope.h, -self.scheduled.shape[0] * floor)
        a = cp.Variable(self.dimension)
        problem = cp.Problem(cp.Minimize(cp.sum_squares(a - raw)), [g @ a <= h])
        problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
        if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            raise ValueError(f"reference projection failed: {problem.status}")
        approx = np.asarray(a.value, dtype=float)
        exact = kkt_polish(g, h, raw, approx)
        return approx if exact is None else exact
