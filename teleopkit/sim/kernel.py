"""Compiled (numba) integrator of the teleoperator: fixed-step Runge–Kutta, delayed Hermite reads.

It implements, for any number of joints and with the method of :mod:`teleopkit.sim.tableau`,
exactly the model of :mod:`teleopkit.model.dynamics`,
:mod:`teleopkit.model.laws` and :mod:`teleopkit.delays.history`; the readable
:mod:`teleopkit.sim.numpy_integrator` is what the tests compare it with. States follow
:class:`teleopkit.sim.state.StateLayout` (``12 n`` values per scenario; the kernel addresses its
blocks by constant offsets, which the comparison with the numpy integrator checks).

Layout for speed (measured reasons in ``docs/benchmark_history.md``):

- The batch is cut into blocks of :data:`LANES` scenarios, integrated in parallel (``prange``).
  Inside a block the state is stored structure-of-arrays (``[variable, lane]``) and each
  stage runs three loops over lanes without calls or branches (the sine and cosine are an
  inlined polynomial, :func:`~teleopkit.sim.trig.sincos`), which LLVM vectorises: the delayed
  history reads (gathers), the motion (controllers, springs and the two arms' accelerations)
  and the integrands of the cost and energy terms. One loop writing all the slopes stayed
  scalar (motion and integrands of one derivative, timed alone at batch 4096 on one thread:
  31 ns in one loop, 10 ns in two).
- Those loops sit in the body of the parallel loop itself: the block body is inlined there by
  numba (``inline="always"``), and the scratch arrays are allocated before the loop, so numba
  passes them to the body as ``noalias`` arguments, which the vectoriser needs. Inlined later
  by LLVM (``forceinline``) the block body was optimised as a separate function and its loops
  stayed scalar (a whole derivative evaluation at batch 4096 on one thread: 60 ns, 37 ns
  inlined by numba). The other helpers are ``forceinline`` and take whole arrays plus indices,
  never views or tuples of arrays (both cost reference counting, and views alias).
- When every delay of a call exceeds the step (no read falls inside the current step), a delayed
  read depends on the stage time only, and a two-link block reads the history at four of the six
  stages: the second stage at a quarter step and the next step's first stage reuse the reads of
  the stages at the same times (bit for bit). Delays that jump (:mod:`teleopkit.delays.jumps`)
  keep the step's first read: its last stage reads the left limits at the step's end.
- Delays come as one shape of time per channel times a scale per scenario when both profiles
  have ``factors`` (the paper's Fourier profile, constant delays; see :func:`advance`): the
  kernel multiplies as it reads instead of reading ``S B`` delays sampled by numpy (26 MB per
  25-period call at batch 4096), the same products bit for bit.
- Model constants are one plain array (:func:`kernel_model`); a tuple of arrays would be reference
  counted at every read. A batch of several plants has a column per scenario, read like the
  operator motion's column (the lane's own, or the one shared).
- Two-link arms use a closed-form inertia solve; other arms a generic scalar Cholesky path.
- A block of one scenario (a single run, or the last block of a batch) runs the per-variable
  loops without their lane loop: the vectorised loop's set-up for one lane took about half of
  a single scenario's time (a 40 s run: 17 ms, 9 ms without).
- A batch of one block (at most :data:`LANES` scenarios) runs the same block body outside the
  parallel loop: launching the parallel loop cost about a fifth of a single scenario's control
  period (23.5 us, 19 us without), and waking the other threads for one block only costs time.
  The thread count of numba is never changed here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit, prange

from teleopkit.model.dynamics import inertia_coefficients
from teleopkit.model.params import TeleoperatorParams, Wall
from teleopkit.sim._kernel_reads import delay_at, delays_exceed, interpolate, locate
from teleopkit.sim.state import FIELDS
from teleopkit.sim.tableau import ROWS, ROWS_PER_STEP, STAGES, A, B, C
from teleopkit.sim.trig import sincos

__all__ = ["BLOCKS", "LANES", "advance", "kernel_model"]

LANES = 32
"""Scenarios per block: the unit of parallel work and the length of the vectorised loops."""

BLOCKS = len(FIELDS)
"""Blocks of ``n`` values in a state (:class:`~teleopkit.sim.state.StateLayout`)."""


_REPEATED = next(r for r in range(1, STAGES) if C[r] == C[r - 1])
"""The stage at the time of the stage before it (a constant: indexing :data:`C` with the stage in
that test kept the lane loops from being vectorised, 2.5 against 1.36 M env-steps/s)."""

_READ_AT_STAGES = tuple(FIELDS.index(name) for name in (
    "ql", "dql", "qr", "dqr", "theta", "dtheta", "int_dql2", "int_dtheta2"))
"""The state blocks a derivative reads: the motion, and the single integrals whose value is the
slope of a double integral."""

# Rows of the model array (see kernel_model).
_KL, _BL, _STIFFNESS, _ROTOR_INV, _WALL, _KS, _KD, _LIMIT, _WALL_K, _WALL_D = range(10)
_INERTIA = 10


def kernel_model(plants: Sequence[TeleoperatorParams],
                 plant_index: np.ndarray | None = None) -> np.ndarray:
    """Pack the constants of the plants into one array, the form the kernel takes.

    Parameters
    ----------
    plants : sequence of TeleoperatorParams
        The teleoperators of the batch (the same number of joints).
    plant_index : ndarray of int, shape (B,), optional
        The plant each scenario runs; without it the batch shares ``plants[0]``.

    Returns
    -------
    ndarray, shape (10 + 2 n, n, K)
        Per joint: rows ``K_l, B_l, S_r, 1 / J_r``, wall position, ``K_s, K_d``, torque limit, wall
        stiffness and damping (scalars repeated per joint); then the inertia coefficients ``a_ij``
        (:func:`teleopkit.model.dynamics.inertia_coefficients`) of the local arm (``n`` rows) and
        of the remote arm (``n`` rows). Column ``b`` of the last axis is scenario ``b``'s plant
        (``K = B``), or the one plant of the batch (``K = 1``). A plain array passes through
        numba's parallel loop and is read without reference counting.
    """
    columns = [_plant_columns(params) for params in plants]
    if plant_index is None or len(plants) == 1:
        return columns[0][..., None]
    return np.ascontiguousarray(np.stack(columns, axis=-1)[..., np.asarray(plant_index)])


def _plant_columns(params: TeleoperatorParams) -> np.ndarray:
    """The constants of one plant, shape ``(10 + 2 n, n)`` (rows as in :func:`kernel_model`)."""
    n = params.n_joints
    wall = params.environment if isinstance(params.environment, Wall) else None
    joint = [params.local_gains.stiffness, params.local_gains.damping, params.joints.stiffness,
             1.0 / np.array(params.joints.rotor_inertia),
             wall.position if wall else (math.inf,) * n]
    scalars = [params.operator.stiffness, params.operator.damping, params.torque_limit,
               wall.stiffness if wall else 0.0, wall.damping if wall else 0.0]
    return np.vstack([np.array(joint), np.repeat(np.array(scalars)[:, None], n, axis=1),
                      inertia_coefficients(params.local_arm),
                      inertia_coefficients(params.remote_arm)])


@njit(cache=True, error_model="numpy", forceinline=True)
def _joint(m, c, i, ql, dql, qr, dqr, th, dth, ql_delayed, th_delayed, qh, kr, br):
    """Controllers, operator, environment and spring of joint ``i`` of the plant ``m[..., c]``.

    Returns the torque on the local link, the torque on the remote link and the motor acceleration.
    """
    lim = m[_LIMIT, i, c]
    tau_l = min(max(m[_KL, i, c] * (ql - th_delayed) + m[_BL, i, c] * dql, -lim), lim)
    tau_r = min(max(-kr * (th - ql_delayed) - br * dth, -lim), lim)
    tau_h = m[_KS, i, c] * (qh - ql) - m[_KD, i, c] * dql
    depth = qr - m[_WALL, i, c]
    tau_e = max(0.0, m[_WALL_K, i, c] * depth + m[_WALL_D, i, c] * dqr) if depth > 0 else 0.0
    spring = m[_STIFFNESS, i, c] * (qr - th)
    return tau_h - tau_l, -spring - tau_e, (tau_r + spring) * m[_ROTOR_INV, i, c]


@njit(cache=True, error_model="numpy", forceinline=True)
def _two_link_acceleration(m, c, arm, q2, dq1, dq2, tau1, tau2):
    """Closed form of :func:`_arm_acceleration` for two links: ``(q1'', q2'')``."""
    first = _INERTIA + 2 * arm
    a12, a22 = m[first, 1, c], m[first + 1, 1, c]
    s, cos = sincos(q2)
    m12 = a22 + a12 * cos
    m11 = m[first, 0, c] + a12 * cos + m12
    h2 = a12 * s * dq1 * dq1
    h1 = h2 - a12 * s * (dq1 + dq2) * (dq1 + dq2)
    r1 = tau1 - h1
    r2 = tau2 - h2
    inv_det = 1.0 / (m11 * a22 - m12 * m12)
    return (a22 * r1 - m12 * r2) * inv_det, (m11 * r2 - m12 * r1) * inv_det


@njit(cache=True, error_model="numpy", forceinline=True)
def _two_link_delayed(hist, initial, delays, drow, scale, clock, frac, dt, st, delayed, b, lo, w):
    """Write lane ``w``'s delayed reads ``[q_l1, q_l2, theta_1, theta_2]`` to ``delayed[b, :, w]``.

    The stage state is ``st[b, :, w]``, its delays row ``drow`` of ``delays``; ``clock`` is
    ``(k, newest, row, p)``: newest stored grid step, its ring slot, input row of the stage time
    and control period; ``frac`` is the stage time minus ``t_k`` in steps and ``lo`` the block's
    first scenario.
    """
    k, newest, _, _ = clock
    lane = lo + w
    length = hist.shape[2]
    to_remote = locate(k, newest, frac, delay_at(delays, scale, drow, 0, lane), dt, length)
    to_local = locate(k, newest, frac, delay_at(delays, scale, drow, 1, lane), dt, length)
    delayed[b, 0, w] = interpolate(hist, lane, 0, 0, to_remote, st[b, 0, w], st[b, 2, w], initial)
    delayed[b, 1, w] = interpolate(hist, lane, 0, 1, to_remote, st[b, 1, w], st[b, 3, w], initial)
    delayed[b, 2, w] = interpolate(hist, lane, 1, 0, to_local, st[b, 8, w], st[b, 10, w], initial)
    delayed[b, 3, w] = interpolate(hist, lane, 1, 1, to_local, st[b, 9, w], st[b, 11, w], initial)


@njit(cache=True, error_model="numpy", forceinline=True)
def _two_link_lane(m, c, qh, qh_gain, gains, clock, st, delayed, slopes, b, r, lo, w):
    """Write the motion slopes ``slopes[b, r, :12, w]`` of lane ``w`` of a two-link block.

    The stage is ``r``, its state ``st[b, :, w]`` and its delayed reads ``delayed[b, :, w]``
    (:func:`_two_link_delayed`); ``clock`` as there.
    """
    _, _, row, p = clock
    lane = lo + w
    col = min(lane, qh.shape[1] - 1)  # the batch's shared motion, or the lane's own
    ql1, ql2, dql1, dql2 = st[b, 0, w], st[b, 1, w], st[b, 2, w], st[b, 3, w]
    qr1, qr2, dqr1, dqr2 = st[b, 4, w], st[b, 5, w], st[b, 6, w], st[b, 7, w]
    th1, th2, dth1, dth2 = st[b, 8, w], st[b, 9, w], st[b, 10, w], st[b, 11, w]
    local1, link1, ddth1 = _joint(m, c, 0, ql1, dql1, qr1, dqr1, th1, dth1, delayed[b, 0, w],
                                  delayed[b, 2, w], qh[row, col, 0] * qh_gain[lane, 0],
                                  gains[p, lane, 0], gains[p, lane, 2])
    local2, link2, ddth2 = _joint(m, c, 1, ql2, dql2, qr2, dqr2, th2, dth2, delayed[b, 1, w],
                                  delayed[b, 3, w], qh[row, col, 1] * qh_gain[lane, 1],
                                  gains[p, lane, 1], gains[p, lane, 3])
    ddql1, ddql2 = _two_link_acceleration(m, c, 0, ql2, dql1, dql2, local1, local2)
    ddqr1, ddqr2 = _two_link_acceleration(m, c, 1, qr2, dqr1, dqr2, link1, link2)
    slopes[b, r, 0, w], slopes[b, r, 1, w] = dql1, dql2
    slopes[b, r, 2, w], slopes[b, r, 3, w] = ddql1, ddql2
    slopes[b, r, 4, w], slopes[b, r, 5, w] = dqr1, dqr2
    slopes[b, r, 6, w], slopes[b, r, 7, w] = ddqr1, ddqr2
    slopes[b, r, 8, w], slopes[b, r, 9, w] = dth1, dth2
    slopes[b, r, 10, w], slopes[b, r, 11, w] = ddth1, ddth2


@njit(cache=True, error_model="numpy", forceinline=True)
def _two_link_integrands(st, delayed, slopes, b, r, w):
    """Write the slopes ``slopes[b, r, 12:, w]`` of the integrals (the cost and energy terms)."""
    for i in range(2):
        slopes[b, r, 12 + i, w] = st[b, 8 + i, w] - delayed[b, i, w]
        slopes[b, r, 14 + i, w] = st[b, 8 + i, w] - st[b, 4 + i, w]
        slopes[b, r, 16 + i, w] = st[b, 2 + i, w] * st[b, 2 + i, w]
        slopes[b, r, 18 + i, w] = st[b, 16 + i, w]
        slopes[b, r, 20 + i, w] = st[b, 10 + i, w] * st[b, 10 + i, w]
        slopes[b, r, 22 + i, w] = st[b, 20 + i, w]


@njit(cache=True, error_model="numpy", forceinline=True)
def _arm_acceleration(m, c, arm, x, b, w, first, work, slopes, r):
    """Solve ``M(q) q'' = torque - C(q, q') q'`` for any number of links (:mod:`.dynamics`).

    ``q`` and ``q'`` are ``x[b, first:first + n, w]`` and ``x[b, first + n:first + 2 n, w]``, the
    torque is ``work[b, n + arm]`` (arm 0: local, 1: remote); ``q''`` is written to
    ``slopes[b, r, first + n:first + 2 n, w]``. Rows ``:n`` and ``n + 2:`` of ``work[b]`` are
    scratch.
    """
    n = work.shape[2]
    coef = _INERTIA + n * arm
    phi, dphi, coriolis = n + 2, n + 3, n + 4  # rows of work[b]
    angle = 0.0
    rate = 0.0
    for i in range(n):
        angle += x[b, first + i, w]
        rate += x[b, first + n + i, w]
        work[b, phi, i] = angle
        work[b, dphi, i] = rate
        work[b, coriolis, i] = 0.0
        work[b, i, i] = m[coef + i, i, c]
    for i in range(n):
        for j in range(i + 1, n):
            s, cos = sincos(work[b, phi, i] - work[b, phi, j])
            a = m[coef + i, j, c]
            work[b, i, j] = a * cos
            work[b, j, i] = a * cos
            work[b, coriolis, i] += a * s * work[b, dphi, j] * work[b, dphi, j]
            work[b, coriolis, j] -= a * s * work[b, dphi, i] * work[b, dphi, i]
    for j in range(n):  # M = T^T M_abs T: suffix sums over rows, then columns
        for i in range(n - 2, -1, -1):
            work[b, i, j] += work[b, i + 1, j]
    for i in range(n):
        for j in range(n - 2, -1, -1):
            work[b, i, j] += work[b, i, j + 1]
    for i in range(n - 2, -1, -1):
        work[b, coriolis, i] += work[b, coriolis, i + 1]
    for i in range(n):
        work[b, dphi, i] = work[b, n + arm, i] - work[b, coriolis, i]
    _cholesky_solve(work, b, dphi)
    for i in range(n):
        slopes[b, r, first + n + i, w] = work[b, dphi, i]


@njit(cache=True, error_model="numpy", forceinline=True)
def _cholesky_solve(work, b, row):
    """Solve ``A y = work[b, row]`` in place, ``A = work[b, :n]`` (SPD, overwritten)."""
    n = work.shape[2]
    for j in range(n):
        d = work[b, j, j]
        for k in range(j):
            d -= work[b, j, k] * work[b, j, k]
        work[b, j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = work[b, i, j]
            for k in range(j):
                s -= work[b, i, k] * work[b, j, k]
            work[b, i, j] = s / work[b, j, j]
    for i in range(n):
        for k in range(i):
            work[b, row, i] -= work[b, i, k] * work[b, row, k]
        work[b, row, i] /= work[b, i, i]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            work[b, row, i] -= work[b, k, i] * work[b, row, k]
        work[b, row, i] /= work[b, i, i]


@njit(cache=True, error_model="numpy", forceinline=True)
def _generic_lane(m, hist, initial, delays, drow, scale, qh, qh_gain, gains, clock, frac, dt, st,
                  slopes, b, r, lo, w, work):
    """The reads, motion and integrands of the two-link loops, for any number of joints.

    One loop body does what :func:`_two_link_delayed`, :func:`_two_link_lane` and
    :func:`_two_link_integrands` do, with the stage's delays in row ``drow`` of ``delays``;
    ``work[b]`` ``(n + 5, n)`` is scratch.
    """
    k, newest, row, p = clock
    lane = lo + w
    length = hist.shape[2]
    n = initial.shape[2]
    col = min(lane, qh.shape[1] - 1)
    c = min(lane, m.shape[2] - 1)
    to_remote = locate(k, newest, frac, delay_at(delays, scale, drow, 0, lane), dt, length)
    to_local = locate(k, newest, frac, delay_at(delays, scale, drow, 1, lane), dt, length)
    for i in range(n):
        ql = interpolate(hist, lane, 0, i, to_remote, st[b, i, w], st[b, n + i, w], initial)
        th = interpolate(hist, lane, 1, i, to_local, st[b, 4 * n + i, w], st[b, 5 * n + i, w],
                          initial)
        work[b, n, i], work[b, n + 1, i], slopes[b, r, 5 * n + i, w] = _joint(
            m, c, i, st[b, i, w], st[b, n + i, w], st[b, 2 * n + i, w], st[b, 3 * n + i, w],
            st[b, 4 * n + i, w], st[b, 5 * n + i, w], ql, th, qh[row, col, i] * qh_gain[lane, i],
            gains[p, lane, i], gains[p, lane, n + i])
        slopes[b, r, i, w] = st[b, n + i, w]
        slopes[b, r, 2 * n + i, w] = st[b, 3 * n + i, w]
        slopes[b, r, 4 * n + i, w] = st[b, 5 * n + i, w]
        slopes[b, r, 6 * n + i, w] = st[b, 4 * n + i, w] - ql
        slopes[b, r, 7 * n + i, w] = st[b, 4 * n + i, w] - st[b, 2 * n + i, w]
        slopes[b, r, 8 * n + i, w] = st[b, n + i, w] * st[b, n + i, w]
        slopes[b, r, 9 * n + i, w] = st[b, 8 * n + i, w]
        slopes[b, r, 10 * n + i, w] = st[b, 5 * n + i, w] * st[b, 5 * n + i, w]
        slopes[b, r, 11 * n + i, w] = st[b, 10 * n + i, w]
    _arm_acceleration(m, c, 0, st, b, w, 0, work, slopes, r)
    _arm_acceleration(m, c, 1, st, b, w, 2 * n, work, slopes, r)


@njit(cache=True, error_model="numpy", forceinline=True)
def _stage_entry(xs, k, st, b, r, h, v, w):
    """``st[b, v, w] = xs[b, v, w] + h sum_j A[r, j] k[b, j, v, w]``.

    Over :data:`A`'s non-zero entries, summed in order as :mod:`.numpy_integrator` does.
    """
    x = xs[b, v, w]
    if r == 0:
        st[b, v, w] = x
    elif r == 1:
        st[b, v, w] = x + h * (A[1, 0] * k[b, 0, v, w])
    elif r == 2:
        st[b, v, w] = x + h * (A[2, 0] * k[b, 0, v, w] + A[2, 1] * k[b, 1, v, w])
    elif r == 3:
        st[b, v, w] = x + h * (A[3, 1] * k[b, 1, v, w] + A[3, 2] * k[b, 2, v, w])
    elif r == 4:
        st[b, v, w] = x + h * (A[4, 0] * k[b, 0, v, w] + A[4, 3] * k[b, 3, v, w])
    else:
        st[b, v, w] = x + h * (A[5, 0] * k[b, 0, v, w] + A[5, 1] * k[b, 1, v, w]
                               + A[5, 2] * k[b, 2, v, w] + A[5, 3] * k[b, 3, v, w]
                               + A[5, 4] * k[b, 4, v, w])


@njit(cache=True, error_model="numpy", forceinline=True)
def _stage_state(xs, slopes, st, b, r, h, width):
    """Stage ``r``'s state of block ``b`` in ``st[b]``, for the blocks a derivative reads.

    The integrated tracking and damping errors and the double integrals are never read by a
    derivative, so their stage values are not formed.
    """
    n = xs.shape[1] // BLOCKS
    for block in _READ_AT_STAGES:
        for v in range(block * n, (block + 1) * n):
            if width == 1:  # one scenario (module notes)
                _stage_entry(xs, slopes, st, b, r, h, v, 0)
            else:
                for w in range(width):
                    _stage_entry(xs, slopes, st, b, r, h, v, w)


@njit(cache=True, error_model="numpy", forceinline=True)
def _update_entry(xs, k, b, dt, v, w):
    xs[b, v, w] += dt * (B[0] * k[b, 0, v, w] + B[2] * k[b, 2, v, w] + B[3] * k[b, 3, v, w]
                         + B[4] * k[b, 4, v, w] + B[5] * k[b, 5, v, w])


@njit(cache=True, error_model="numpy", forceinline=True)
def _step_update(xs, slopes, b, dt, width):
    """Advance ``xs[b]`` by one step from the stage slopes (weights :data:`B`; ``B[1]`` is 0)."""
    for v in range(xs.shape[1]):
        if width == 1:
            _update_entry(xs, slopes, b, dt, v, 0)
        else:
            for w in range(width):
                _update_entry(xs, slopes, b, dt, v, w)


@njit(cache=True, error_model="numpy", forceinline=True)
def _transfer(x, xs, b, lo, width, to_block):
    """Copy scenarios ``lo:lo + width`` from ``x`` into block ``xs[b]`` or back."""
    for v in range(x.shape[1]):
        for w in range(width):
            if to_block:
                xs[b, v, w] = x[lo + w, v]
            else:
                x[lo + w, v] = xs[b, v, w]


@njit(cache=True, error_model="numpy", forceinline=True)
def _record(hist, slot, xs, b, lo, width):
    """Store the block's channel signals (positions, then velocities) in ring slot ``slot``."""
    n = xs.shape[1] // BLOCKS
    for c in range(2):
        for v in range(2 * n):
            if width == 1:
                hist[lo, c, slot, v] = xs[b, 4 * n * c + v, 0]
            else:
                for w in range(width):
                    hist[lo + w, c, slot, v] = xs[b, 4 * n * c + v, w]


@njit(cache=True, error_model="numpy", forceinline=True)
def _emit(hist, initial, delays, scale, k, row, p, dt, xs, b, lo, width, out_state,
          out_delayed):
    """Write the block's state and delayed signals at the end of period ``p``.

    That is grid step ``k``, input row ``row``.
    """
    length = hist.shape[2]
    n = initial.shape[2]
    for w in range(width):
        lane = lo + w
        for c in range(2):
            where = locate(k, k % length, 0.0, delay_at(delays, scale, row, c, lane), dt, length)
            for i in range(n):
                out_delayed[p, lane, c, i] = interpolate(
                    hist, lane, c, i, where, xs[b, 4 * n * c + i, w],
                    xs[b, 4 * n * c + n + i, w], initial)
        for v in range(xs.shape[1]):
            out_state[p, lane, v] = xs[b, v, w]


@njit(cache=True, error_model="numpy", inline="always")
def _advance_block(m, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain,
                   gains, out_state, out_delayed, xs, st, slopes, work, delayed, b, lo, width,
                   reuse):
    """Integrate block ``b`` (scenarios ``lo`` to ``lo + width``) over every period.

    With ``reuse`` (every delay of the call is longer than ``dt``:
    :func:`~teleopkit.sim._kernel_reads.delays_exceed`) no delayed read falls inside the current
    step, so a read depends on the stage time only: the second quarter-step stage reuses the
    first's reads and a step's first stage the previous step's last (the same times and delay
    samples, hence the same values bit for bit; not when the delays jump, whose left limit the
    last stage reads).
    """
    dim = xs.shape[1]
    length = hist.shape[2]
    jumps = left.shape[0] > 0
    for p in range(gains.shape[0]):
        for s in range(substeps):
            k = step0 + p * substeps + s
            newest = k % length
            for r in range(STAGES):
                clock = (k, newest, ROWS_PER_STEP * (p * substeps + s) + ROWS[r], p)
                frac = C[r]
                _stage_state(xs, slopes, st, b, r, dt, width)
                # The loops over lanes stay in the parallel body (this helper is inlined there
                # by numba), where LLVM vectorises them (module notes).
                if dim == 2 * BLOCKS:
                    # Left limits at the step's end in a loop of their own: one loop over an
                    # array chosen per stage kept the lane loops scalar (1.22 against 2.4 M
                    # env-steps/s at batch 4096).
                    if jumps and r == STAGES - 1:
                        for w in range(width):
                            _two_link_delayed(hist, initial, left, p * substeps + s, scale,
                                              clock, frac, dt, st, delayed, b, lo, w)
                    elif not (reuse and (r == _REPEATED or (r == 0 and p + s > 0 and not jumps))):
                        for w in range(width):
                            _two_link_delayed(hist, initial, delays, clock[2], scale, clock, frac,
                                              dt, st, delayed, b, lo, w)
                    if m.shape[2] == 1:
                        for w in range(width):
                            _two_link_lane(m, 0, qh, qh_gain, gains, clock, st, delayed, slopes,
                                           b, r, lo, w)
                    else:
                        for w in range(width):
                            _two_link_lane(m, lo + w, qh, qh_gain, gains, clock, st, delayed,
                                           slopes, b, r, lo, w)
                    for w in range(width):
                        _two_link_integrands(st, delayed, slopes, b, r, w)
                elif jumps and r == STAGES - 1:
                    for w in range(width):
                        _generic_lane(m, hist, initial, left, p * substeps + s, scale, qh, qh_gain,
                                      gains, clock, frac, dt, st, slopes, b, r, lo, w, work)
                else:
                    for w in range(width):
                        _generic_lane(m, hist, initial, delays, clock[2], scale, qh, qh_gain,
                                      gains, clock, frac, dt, st, slopes, b, r, lo, w, work)
            _step_update(xs, slopes, b, dt, width)
            _record(hist, newest + 1 if newest + 1 < length else 0, xs, b, lo, width)
        _emit(hist, initial, delays, scale, step0 + (p + 1) * substeps,
              ROWS_PER_STEP * (p + 1) * substeps, p, dt, xs, b, lo, width, out_state, out_delayed)


@njit(cache=True, error_model="numpy", forceinline=True)
def _scratch(blocks, dim):
    """Per-block state, stage state, the stage slopes and the generic path's work rows."""
    n = dim // BLOCKS
    return (np.empty((blocks, dim, LANES)), np.empty((blocks, dim, LANES)),
            np.empty((blocks, STAGES, dim, LANES)), np.empty((blocks, n + 5, n)),
            np.empty((blocks, 2 * n, LANES)))


@njit(cache=True, error_model="numpy", parallel=True)
def _advance(m, x, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain, gains,
             out_state, out_delayed, reuse):
    batch, dim = x.shape
    blocks = (batch + LANES - 1) // LANES
    # The scratch is allocated outside the parallel loop so that it reaches it as noalias
    # arguments.
    xs, st, slopes, work, delayed = _scratch(blocks, dim)
    # Before the parallel loop: a call on an array inside its body would cost the noalias flag.
    reuse = reuse and delays_exceed(delays, scale, dt)
    for b in prange(blocks):
        lo = b * LANES
        width = min(LANES, batch - lo)
        _transfer(x, xs, b, lo, width, True)
        _advance_block(m, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain,
                       gains, out_state, out_delayed, xs, st, slopes, work, delayed, b, lo, width,
                       reuse)
        _transfer(x, xs, b, lo, width, False)


@njit(cache=True, error_model="numpy")
def _advance_serial(m, x, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain,
                    gains, out_state, out_delayed, reuse):
    """:func:`_advance` for one block (at most :data:`LANES` scenarios), in this thread.

    Waking the other threads for one block would only cost time (for one scenario the parallel
    launch cost a fifth of the call); the block's arithmetic is the same as in the loop.
    """
    batch = x.shape[0]
    xs, st, slopes, work, delayed = _scratch(1, x.shape[1])
    reuse = reuse and delays_exceed(delays, scale, dt)
    _transfer(x, xs, 0, 0, batch, True)
    _advance_block(m, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain,
                   gains, out_state, out_delayed, xs, st, slopes, work, delayed, 0, 0, batch,
                   reuse)
    _transfer(x, xs, 0, 0, batch, False)


def advance(x: np.ndarray, hist: np.ndarray, initial: np.ndarray, step0: int, dt: float,
            substeps: int, delays: np.ndarray, scale: np.ndarray, left: np.ndarray,
            qh: np.ndarray, qh_gain: np.ndarray, gains: np.ndarray, model: np.ndarray,
            out_state: np.ndarray, out_delayed: np.ndarray) -> None:
    """Integrate ``gains.shape[0]`` control periods of ``substeps`` steps, in place.

    Parameters
    ----------
    x : ndarray, shape (B, 12 n)
        States at grid step ``step0``; overwritten with the final states.
    hist : ndarray, shape (B, 2, L, 2 n)
        Ring buffers of the two channels (channel 0: ``q_l``, channel 1: ``theta_r``): grid step
        ``k`` is in slot ``k % L`` as ``[positions, velocities]``; updated. ``L`` must exceed the
        largest delay by two steps.
    initial : ndarray, shape (B, 2, n)
        Constant past of each channel.
    step0 : int
        Grid index of the current time.
    dt : float
        Integration step.
    substeps : int
        Integration steps per control period.
    delays, scale : ndarray, shapes (4 P substeps + 1, 2, K) and (2, B)
        Forward and backward delays at every stage time (quarter step) from the current time:
        channel ``c`` of scenario ``b`` at row ``s`` is ``delays[s, c, b] * scale[c, b]`` seconds
        with ``K = B`` (one column per scenario; ``scale`` is then ones), or
        ``delays[s, c, 0] * scale[c, b]`` with ``K = 1`` (one shape of time times a scale per
        scenario, a profile's ``factors``).
    left : ndarray, shape (P substeps, 2, K) or (0, 2, K)
        For delays that jump (:mod:`teleopkit.delays.jumps`): their left limits at the end of
        every step, in the factors of ``delays``, which the step's last stage reads (the next
        step's first reads row ``4 (j + 1)`` of ``delays``). Empty for continuous delays.
    qh, qh_gain : ndarray, shapes (4 P substeps + 1, M, n) and (B, n)
        The operator reference at the same times is ``qh[s, b] * qh_gain[b]`` (the reference
        motion with unit gains, times each scenario's gains ``G``), or ``qh[s, 0] * qh_gain[b]``
        when the batch shares one motion (``M = 1``).
    gains : ndarray, shape (P, B, 2 n)
        Remote gains ``[K_r, B_r]`` held over each control period.
    model : ndarray, shape (10 + 2 n, n, K)
        Model constants from :func:`kernel_model`: the batch's one plant (``K = 1``) or each
        scenario's (``K = B``).
    out_state : ndarray, shape (P, B, 12 n)
        Receives the state at the end of each period.
    out_delayed : ndarray, shape (P, B, 2, n)
        Receives ``q_l(t - T_l)`` and ``theta(t - T_r)`` at the end of each period.
    """
    # the last argument allows reusing delayed reads (the tests turn it off to compare)
    args = (model, x, hist, initial, step0, dt, substeps, delays, scale, left, qh, qh_gain,
            gains, out_state, out_delayed, True)
    if x.shape[0] <= LANES:
        _advance_serial(*args)
    else:
        _advance(*args)
