"""Compiled (numba) integrator of the teleoperator: fixed-step RK4 with delayed Hermite read-out.

It implements, for one scenario at a time and for any number of joints, exactly the model of
:mod:`teleopkit.dynamics`, :mod:`teleopkit.control` and :mod:`teleopkit.channel`; the readable numpy
reference in :mod:`teleopkit.reference` is what the tests compare it with. The state of a scenario is
``[q_l, q_l', q_r, q_r', theta, theta', int e_track, int e_damp]`` (``8 n`` values).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from teleopkit.dynamics import inertia_coefficients
from teleopkit.params import TeleoperatorParams, Wall

__all__ = ["KernelModel", "advance", "kernel_model"]


class KernelModel(NamedTuple):
    """Constants of the model in the form the kernel takes (arrays of length ``n``)."""

    local_coef: np.ndarray
    remote_coef: np.ndarray
    stiffness: np.ndarray
    rotor_inertia: np.ndarray
    kl: np.ndarray
    bl: np.ndarray
    ks: float
    kd: float
    torque_limit: float
    wall_position: np.ndarray
    wall_stiffness: float
    wall_damping: float


def kernel_model(params: TeleoperatorParams) -> KernelModel:
    """Pack ``params`` for the kernel."""
    wall = params.environment if isinstance(params.environment, Wall) else None
    n = params.n_joints
    return KernelModel(
        inertia_coefficients(params.local_arm), inertia_coefficients(params.remote_arm),
        np.array(params.joints.stiffness), np.array(params.joints.rotor_inertia),
        np.array(params.local_gains.stiffness), np.array(params.local_gains.damping),
        float(params.operator.stiffness), float(params.operator.damping),
        float(params.torque_limit),
        np.array(wall.position) if wall else np.full(n, np.inf),
        float(wall.stiffness) if wall else 0.0, float(wall.damping) if wall else 0.0,
    )


@njit(cache=True, inline="always")
def _hermite(x0: float, v0: float, x1: float, v1: float, span: float, u: float) -> float:
    u2 = u * u
    u3 = u2 * u
    return ((2 * u3 - 3 * u2 + 1) * x0 + (u3 - 2 * u2 + u) * span * v0
            + (3 * u2 - 2 * u3) * x1 + (u3 - u2) * span * v1)


@njit(cache=True)
def _arm_acceleration(coef, q, dq, torque, mass, work, out):  # type: ignore[no-untyped-def]
    """Solve ``M(q) q'' = torque - C(q, q') q'`` into ``out`` (see :mod:`teleopkit.dynamics`)."""
    n = q.size
    phi, dphi, coriolis = work[0], work[1], work[2]
    angle = 0.0
    rate = 0.0
    for i in range(n):
        angle += q[i]
        rate += dq[i]
        phi[i] = angle
        dphi[i] = rate
        mass[i, i] = coef[i, i]
        coriolis[i] = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            c = math.cos(phi[i] - phi[j])
            s = math.sin(phi[i] - phi[j])
            mass[i, j] = coef[i, j] * c
            mass[j, i] = mass[i, j]
            coriolis[i] += coef[i, j] * s * dphi[j] * dphi[j]
            coriolis[j] -= coef[i, j] * s * dphi[i] * dphi[i]
    for j in range(n):  # T^T M_abs T: suffix sums over rows, then columns
        for i in range(n - 2, -1, -1):
            mass[i, j] += mass[i + 1, j]
    for i in range(n):
        for j in range(n - 2, -1, -1):
            mass[i, j] += mass[i, j + 1]
    for i in range(n - 2, -1, -1):
        coriolis[i] += coriolis[i + 1]
    for i in range(n):
        out[i] = torque[i] - coriolis[i]
    _cholesky_solve(mass, out)


@njit(cache=True)
def _cholesky_solve(a, b):  # type: ignore[no-untyped-def]
    """Solve ``a x = b`` in place (``a`` symmetric positive definite, overwritten)."""
    n = b.size
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        a[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / a[j, j]
    for i in range(n):
        for k in range(i):
            b[i] -= a[i, k] * b[k]
        b[i] /= a[i, i]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            b[i] -= a[k, i] * b[k]
        b[i] /= a[i, i]


@njit(cache=True)
def _derivative(x, delayed, qh, gains, m, mass, work, torque, dx):  # type: ignore[no-untyped-def]
    """Right-hand side of the closed loop for one scenario; ``delayed[0]`` is ``q_l(t - T_l)``,
    ``delayed[1]`` is ``theta(t - T_r)``."""
    n = qh.size
    lim = m.torque_limit
    for i in range(n):
        ql, dql = x[i], x[n + i]
        qr, dqr = x[2 * n + i], x[3 * n + i]
        th, dth = x[4 * n + i], x[5 * n + i]
        tau_l = min(max(m.kl[i] * (ql - delayed[1, i]) + m.bl[i] * dql, -lim), lim)
        tau_r = min(max(-gains[i] * (th - delayed[0, i]) - gains[n + i] * dth, -lim), lim)
        tau_h = m.ks * (qh[i] - ql) - m.kd * dql
        depth = qr - m.wall_position[i]
        tau_e = max(0.0, m.wall_stiffness * depth + m.wall_damping * dqr) if depth > 0 else 0.0
        spring = m.stiffness[i] * (qr - th)
        torque[0, i] = tau_h - tau_l
        torque[1, i] = -spring - tau_e
        dx[i] = dql
        dx[2 * n + i] = dqr
        dx[4 * n + i] = dth
        dx[5 * n + i] = (tau_r + spring) / m.rotor_inertia[i]
        dx[6 * n + i] = th - delayed[0, i]
        dx[7 * n + i] = th - qr
    _arm_acceleration(m.local_coef, x[:n], x[n:2 * n], torque[0], mass, work, dx[n:2 * n])
    _arm_acceleration(m.remote_coef, x[2 * n:3 * n], x[3 * n:4 * n], torque[1], mass, work,
                      dx[3 * n:4 * n])


@njit(cache=True)
def _read(hpos, hvel, initial, k, offset, delay, dt, latest, out):  # type: ignore[no-untyped-def]
    """Delayed read-out of one channel (see :class:`teleopkit.channel.DelayChannel`).

    ``offset`` is the stage time minus ``t_k`` in steps, ``delay`` in steps, ``latest`` the stage's
    ``(position, velocity)`` of the sender, stacked as shape ``(2, n)``.
    """
    length = hpos.shape[0]
    n = out.size
    steps = k + offset - delay
    if steps <= 0.0:
        for i in range(n):
            out[i] = initial[i]
        return
    j = math.floor(steps)
    if j >= k:
        a = k % length
        u = (steps - k) / offset if offset > 0.0 else 0.0
        for i in range(n):
            out[i] = _hermite(hpos[a, i], hvel[a, i], latest[0, i], latest[1, i], offset * dt, u)
        return
    a = j % length
    b = (j + 1) % length
    for i in range(n):
        out[i] = _hermite(hpos[a, i], hvel[a, i], hpos[b, i], hvel[b, i], dt, steps - j)


def _advance(x, hpos, hvel, initial, step0, dt, substeps, delays, qh, gains, m,
             out_state, out_delayed):  # type: ignore[no-untyped-def]
    batch, dim = x.shape
    n = dim // 8
    periods = gains.shape[0]
    for b in prange(batch):
        state = x[b].copy()
        stage = np.empty(dim)
        slopes = np.empty((4, dim))
        delayed = np.empty((2, n))
        latest = np.empty((2, 2, n))
        mass = np.empty((n, n))
        work = np.empty((3, n))
        torque = np.empty((2, n))
        for p in range(periods):
            g = gains[p, b]
            for s in range(substeps):
                k = step0 + p * substeps + s
                row = 2 * (p * substeps + s)
                for r in range(4):
                    frac = (0.0, 0.5, 0.5, 1.0)[r]
                    for i in range(dim):
                        stage[i] = state[i] + (frac * dt) * slopes[r - 1, i] if r else state[i]
                    for c in range(2):
                        first = 4 * n * c  # q_l block for c = 0, theta block for c = 1
                        latest[c, 0] = stage[first:first + n]
                        latest[c, 1] = stage[first + n:first + 2 * n]
                        srow = row + (0, 1, 1, 2)[r]
                        _read(hpos[b, c], hvel[b, c], initial[b, c], k, frac,
                              delays[srow, b, c] / dt, dt, latest[c], delayed[c])
                    _derivative(stage, delayed, qh[row + (0, 1, 1, 2)[r], b], g, m, mass, work,
                                torque, slopes[r])
                for i in range(dim):
                    state[i] += (dt / 6.0) * (slopes[0, i] + 2.0 * (slopes[1, i] + slopes[2, i])
                                              + slopes[3, i])
                slot = (k + 1) % hpos.shape[2]
                for c in range(2):
                    first = 4 * n * c
                    hpos[b, c, slot] = state[first:first + n]
                    hvel[b, c, slot] = state[first + n:first + 2 * n]
            k_end = step0 + (p + 1) * substeps
            row_end = 2 * (p + 1) * substeps
            for c in range(2):
                _read(hpos[b, c], hvel[b, c], initial[b, c], k_end, 0.0,
                      delays[row_end, b, c] / dt, dt, latest[c], out_delayed[p, b, c])
            out_state[p, b] = state
        x[b] = state


_advance_serial = njit(cache=True)(_advance)
_advance_parallel = njit(cache=True, parallel=True)(_advance)


def advance(x: np.ndarray, hpos: np.ndarray, hvel: np.ndarray, initial: np.ndarray, step0: int,
            dt: float, substeps: int, delays: np.ndarray, qh: np.ndarray, gains: np.ndarray,
            model: KernelModel, out_state: np.ndarray, out_delayed: np.ndarray) -> None:
    """Integrate ``gains.shape[0]`` control periods of ``substeps`` RK4 steps, in place.

    Parameters
    ----------
    x : ndarray, shape (B, 8 n)
        States at grid step ``step0``; overwritten with the final states.
    hpos, hvel : ndarray, shape (B, 2, L, n)
        Ring buffers of the two channels' positions and velocities (channel 0: ``q_l``,
        channel 1: ``theta_r``); updated.
    initial : ndarray, shape (B, 2, n)
        Constant past of each channel.
    step0 : int
        Grid index of the current time.
    dt : float
        Integration step.
    substeps : int
        Integration steps per control period.
    delays : ndarray, shape (2 P substeps + 1, B, 2)
        Forward and backward delays at every half step from the current time.
    qh : ndarray, shape (2 P substeps + 1, B, n)
        Operator reference at the same times.
    gains : ndarray, shape (P, B, 2 n)
        Remote gains ``[K_r, B_r]`` held over each control period.
    model : KernelModel
        Model constants.
    out_state : ndarray, shape (P, B, 8 n)
        Receives the state at the end of each period.
    out_delayed : ndarray, shape (P, B, 2, n)
        Receives ``q_l(t - T_l)`` and ``theta(t - T_r)`` at the end of each period.
    """
    kernel = _advance_parallel if x.shape[0] >= 8 else _advance_serial
    kernel(x, hpos, hvel, initial, step0, dt, substeps, delays, qh, gains, model, out_state,
           out_delayed)
