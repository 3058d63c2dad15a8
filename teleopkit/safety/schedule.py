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
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.safety.layer import FLAGS, Projection, SafetyLayer, kkt_polish

__all__ = ["BUDGET", "TANK", "ScheduleLayer", "ScheduleReport", "ScheduleSettings",
           "ScheduleState", "project_scheduled"]

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


class ScheduleSettings(NamedTuple):
    """The class's static set and rules (a NamedTuple: numba compiles it as a record).

    Attributes
    ----------
    shape, rho, beta, b_lo, b_hi : ndarray, shape (n,)
        The common shape, the cone ``B_r^i >= rho_i s_i kappa + beta_i`` and the damping box.
    kappa_lo, kappa_hi : float
        The static interval of ``kappa``.
    mode : int
        :data:`BUDGET` or :data:`TANK`.
    refill : float
        Fraction of the storage released by a rise of ``kappa`` that refills the tank.
    centre : ndarray, shape (2 n,)
        An interior action, applied when nothing finite is available.
    tol : float
        Relative tolerance of the active-constraint report.
    """

    shape: np.ndarray
    rho: np.ndarray
    beta: np.ndarray
    b_lo: np.ndarray
    b_hi: np.ndarray
    kappa_lo: float
    kappa_hi: float
    mode: int
    refill: float
    centre: np.ndarray
    tol: float


class ScheduleState(NamedTuple):
    """The run-time state of a batch's episodes, updated in place by :func:`project_scheduled`.

    Attributes
    ----------
    prev : ndarray, shape (B, 2 n)
        The action applied at the previous step (NaN before the first).
    level : ndarray, shape (B,)
        Budget left (:data:`BUDGET`) or tank level (:data:`TANK`).
    energy : ndarray, shape (B,)
        The remote energy ``E_r`` measured at this sample (tank mode).
    """

    prev: np.ndarray
    level: np.ndarray
    energy: np.ndarray


class ScheduleReport(NamedTuple):
    """What :func:`project_scheduled` writes for each row of a batch.

    Attributes
    ----------
    out : ndarray, shape (B, 2 n)
        The applied actions.
    flags : ndarray of int, shape (B,)
        1 where the raw action was not finite, else 0.
    distance : ndarray, shape (B,)
        ``||out - raw||`` (``inf`` for a non-finite raw action).
    floor : ndarray, shape (B,)
        The floor of ``kappa`` in force at this step.
    active : ndarray of bool, shape (B, 3 + 3 n)
        Constraints that hold with equality (within ``tol`` relative): the floor, the two ends
        of ``kappa``'s interval, the damping box's lower and upper ends, the cones.
    """

    out: np.ndarray
    flags: np.ndarray
    distance: np.ndarray
    floor: np.ndarray
    active: np.ndarray

    @classmethod
    def empty(cls, batch: int, n_joints: int) -> ScheduleReport:
        """Uninitialised arrays for a batch.

        Parameters
        ----------
        batch : int
            Rows.
        n_joints : int
            Joints.

        Returns
        -------
        ScheduleReport
            The arrays, to be filled by :func:`project_scheduled`.
        """
        return cls(np.empty((batch, 2 * n_joints)), np.empty(batch, dtype=np.int64),
                   np.empty(batch), np.empty(batch),
                   np.empty((batch, 3 + 3 * n_joints), dtype=np.bool_))


@njit(forceinline=True, **_OPTIONS)
def _floor(settings: ScheduleSettings, state: ScheduleState, b: int, previous: float) -> float:
    """The step's lowest ``kappa`` of row ``b`` (the static one before the first step)."""
    low = settings.kappa_lo
    if not math.isfinite(previous):
        return low
    if settings.mode == BUDGET:
        low = max(low, previous * math.exp(-state.level[b]))
    elif state.energy[b] > 0.0:
        low = max(low, 1.0 / (1.0 / previous + state.level[b] / state.energy[b]))
    return min(low, previous)  # the previous kappa is always allowed again


@njit(forceinline=True, **_OPTIONS)
def _spend(settings: ScheduleSettings, state: ScheduleState, b: int, previous: float,
           kappa: float) -> None:
    """Charge a change of ``kappa`` of row ``b`` to its budget or tank (rises refill a tank)."""
    if not math.isfinite(previous) or kappa == previous:
        return
    if settings.mode == BUDGET:
        state.level[b] = max(0.0, state.level[b] - max(0.0, math.log(previous / kappa)))
        return
    change = state.energy[b] * (1.0 / kappa - 1.0 / previous)
    state.level[b] = (max(0.0, state.level[b] - change) if change > 0
                      else state.level[b] - settings.refill * change)


@njit(forceinline=True, **_OPTIONS)
def _report_active(settings: ScheduleSettings, report: ScheduleReport, b: int, kappa: float,
                   low: float) -> None:
    """Which constraints row ``b``'s applied action meets with equality."""
    n = settings.shape.size
    tol = settings.tol
    near = tol * (1.0 + abs(kappa))
    report.active[b, 0] = abs(kappa - low) <= near
    report.active[b, 1] = abs(kappa - settings.kappa_lo) <= near
    report.active[b, 2] = abs(kappa - settings.kappa_hi) <= near
    for i in range(n):
        damping = report.out[b, n + i]
        near = tol * (1.0 + abs(damping))
        report.active[b, 3 + i] = abs(damping - settings.b_lo[i]) <= near
        report.active[b, 3 + n + i] = abs(damping - settings.b_hi[i]) <= near
        cone = settings.rho[i] * settings.shape[i] * kappa + settings.beta[i]
        report.active[b, 3 + 2 * n + i] = abs(damping - cone) <= near


@njit(**_OPTIONS)
def project_scheduled(raw: np.ndarray, settings: ScheduleSettings, state: ScheduleState,
                      report: ScheduleReport, kinks: np.ndarray, order: np.ndarray) -> None:
    """Project a batch of raw actions onto the step's set and update the run-time state.

    Parameters
    ----------
    raw : ndarray, shape (B, 2 n)
        Raw actions (NaN and inf allowed: the previous action is applied again, or the
        settings' ``centre`` at the first step).
    settings : ScheduleSettings
        The class's set and rules.
    state : ScheduleState
        The episodes' run-time state; updated (``prev`` becomes the applied actions).
    report : ScheduleReport
        Receives the applied actions and what the projection did.
    kinks : ndarray, shape (n,)
        Scratch.
    order : ndarray of int, shape (n,)
        Scratch.
    """
    n = settings.shape.size
    shape = settings.shape
    for b in range(raw.shape[0]):
        previous = state.prev[b, 0] / shape[0]
        has_prev = math.isfinite(previous)
        low = _floor(settings, state, b, previous)
        report.floor[b] = low
        finite = True
        for c in range(2 * n):
            if not math.isfinite(raw[b, c]):
                finite = False
        if finite:
            best = _minimiser(raw[b], shape, settings.rho, settings.beta, settings.b_lo, kinks,
                              order)
            kappa = min(max(best, low), settings.kappa_hi)
            total = 0.0
            for i in range(n):
                cone = settings.rho[i] * shape[i] * kappa + settings.beta[i]
                report.out[b, i] = kappa * shape[i]
                report.out[b, n + i] = min(max(raw[b, n + i], max(settings.b_lo[i], cone)),
                                           settings.b_hi[i])
            for c in range(2 * n):
                total += (report.out[b, c] - raw[b, c]) ** 2
            report.flags[b], report.distance[b] = 0, math.sqrt(total)
        else:
            kappa = previous if has_prev else settings.centre[0] / shape[0]
            for c in range(2 * n):
                report.out[b, c] = state.prev[b, c] if has_prev else settings.centre[c]
            report.flags[b], report.distance[b] = 1, math.inf
        _spend(settings, state, b, previous, kappa)
        _report_active(settings, report, b, kappa, low)
        for c in range(2 * n):
            state.prev[b, c] = report.out[b, c]


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
        self._mode = TANK if allowed.rule == "tank" else BUDGET
        self._centre = allowed.centre()
        self._settings = ScheduleSettings(*allowed.arrays(), allowed.kappa_low,
                                          allowed.kappa_high, self._mode, allowed.refill,
                                          self._centre, self.tol)
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
        report = ScheduleReport.empty(count, self.scheduled.n_joints)
        # a first step: no previous action, hence no floor and nothing spent
        first = ScheduleState(np.full_like(flat, np.nan), np.full(count, self.scheduled.initial),
                              np.zeros(count))
        project_scheduled(flat, self._settings, first, report, *self._scratch)
        return report.out.reshape(raw.shape)

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
        report = ScheduleReport.empty(shape[0], self.scheduled.n_joints)
        state = ScheduleState(self._prev, self._level, self._energy)
        project_scheduled(flat, self._settings, state, report, *self._scratch)
        out, flags, distance, self.last_floor, active = report
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
