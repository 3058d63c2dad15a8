"""Batched fixed-step simulator of the delayed teleoperator.

The remote gains are held over each control period (10 ms by default) and the model is integrated
with RK4 at a fixed step (:data:`DEFAULT_DT`, 1.25 ms, by default).
Delays and the operator reference are sampled at every half step in numpy; the compiled kernel
(``backend="compiled"``) or the numpy reference (``backend="reference"``) integrates. A batch of
scenarios shares the model; the batch axis comes first in every array.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from teleopkit import _kernel
from teleopkit.delays import DelayProfile, parse_delay
from teleopkit.metrics import error_metrics
from teleopkit.params import TeleoperatorParams, paper_setup
from teleopkit.reference import ReferenceIntegrator
from teleopkit.scenarios import Scenario, sample_reference_gains

__all__ = ["DEFAULT_DT", "Simulator", "StepResult", "Trajectory", "check_gains", "simulate"]

DEFAULT_DT = 0.00125
"""Default integration step (s): 8 RK4 steps per 10 ms control period, at most 7e-6 rad from a
converged solution over the paper's 40 s episode (2.5 ms, the largest step below RK4's stability
limit of about 2.7 ms on this model, is 16 times less accurate; ``benchmarks/README.md``)."""

Backend = Literal["compiled", "reference"]


def check_gains(gains: np.ndarray, n_joints: int) -> np.ndarray:
    """Validate remote gains ``[K_r, B_r]`` (finite, non-negative, last axis ``2 n``).

    Parameters
    ----------
    gains : ndarray, shape (..., 2 n)
        Gains to check.
    n_joints : int
        Number of joints.

    Returns
    -------
    ndarray
        The gains as a float array.
    """
    gains = np.asarray(gains, dtype=float)
    if gains.shape[-1:] != (2 * n_joints,):
        raise ValueError(f"remote gains need {2 * n_joints} values [K_r..., B_r...] on the last "
                         f"axis, got shape {gains.shape}")
    if not np.all(np.isfinite(gains)) or np.any(gains < 0):
        raise ValueError("remote gains must be finite and non-negative")
    return gains


@dataclass(frozen=True)
class StepResult:
    """Outcome of :meth:`Simulator.advance` over ``P`` control periods.

    Attributes
    ----------
    t : ndarray, shape (P,)
        End time of each period.
    state : ndarray, shape (P, B, 8 n)
        ``[q_l, q_l', q_r, q_r', theta, theta', int e_track, int e_damp]`` at each time.
    delayed : ndarray, shape (P, B, 2, n)
        ``q_l(t - T_l)`` and ``theta(t - T_r)``.
    delays : ndarray, shape (P, B, 2)
        ``T_l(t)`` and ``T_r(t)``.
    """

    t: np.ndarray
    state: np.ndarray
    delayed: np.ndarray
    delays: np.ndarray


@dataclass(frozen=True)
class Trajectory(StepResult):
    """A recorded run: a :class:`StepResult` from ``t = 0`` including the initial row.

    ``P`` is the number of recorded times: the control periods of the run plus the row at
    ``t = 0``.

    Attributes
    ----------
    t : ndarray, shape (P,)
        Recorded times in seconds: ``0`` then the end time of each period.
    state : ndarray, shape (P, B, 8 n)
        ``[q_l, q_l', q_r, q_r', theta, theta', int e_track, int e_damp]`` at each time (row 0
        is the initial state).
    delayed : ndarray, shape (P, B, 2, n)
        ``q_l(t - T_l)`` and ``theta(t - T_r)`` (row 0 holds the constant past, the initial
        ``q_l`` and ``theta``).
    delays : ndarray, shape (P, B, 2)
        ``T_l(t)`` and ``T_r(t)`` in seconds.
    gains : ndarray, shape (P, B, 2 n)
        Remote gains in force at each time (row 0 holds the first period's gains).
    """

    gains: np.ndarray

    def _block(self, index: int) -> np.ndarray:
        n = self.state.shape[-1] // 8
        return self.state[..., index * n:(index + 1) * n]

    @property
    def e_track(self) -> np.ndarray:
        """Tracking error ``theta_r - q_l(t - T_l)``, shape ``(P, B, n)``."""
        return self._block(4) - self.delayed[..., 0, :]

    @property
    def e_damp(self) -> np.ndarray:
        """Damping (flexibility) error ``theta_r - q_r``, shape ``(P, B, n)``."""
        return self._block(4) - self._block(2)

    def metrics(self) -> pd.DataFrame:
        """RMS, IAE and maximum of the tracking and damping errors, one row per scenario."""
        return error_metrics(self.t, {"track": self.e_track, "damp": self.e_damp})

    def to_frame(self, scenario: int = 0) -> pd.DataFrame:
        """One scenario as a table with columns ``t, ql_i, qr_i, theta_i, ..., e_damp_i``.

        Parameters
        ----------
        scenario : int
            Index of the scenario in the batch, from 0.

        Returns
        -------
        pandas.DataFrame
            One row per recorded time, columns ``t, ql_i, dql_i, qr_i, dqr_i, theta_i,
            dtheta_i, Tl, Tr, ql_delayed_i, theta_delayed_i, e_track_i, e_damp_i, Kr_i, Br_i``
            (``i`` the joint, from 1).
        """
        n = self.state.shape[-1] // 8
        blocks = {"ql": 0, "dql": 1, "qr": 2, "dqr": 3, "theta": 4, "dtheta": 5}
        columns: dict[str, np.ndarray] = {"t": self.t}
        for name, index in blocks.items():
            for i in range(n):
                columns[f"{name}_{i + 1}"] = self._block(index)[:, scenario, i]
        columns["Tl"] = self.delays[:, scenario, 0]
        columns["Tr"] = self.delays[:, scenario, 1]
        for name, signal in (("ql_delayed", self.delayed[:, scenario, 0]),
                             ("theta_delayed", self.delayed[:, scenario, 1]),
                             ("e_track", self.e_track[:, scenario]),
                             ("e_damp", self.e_damp[:, scenario]),
                             ("Kr", self.gains[:, scenario, :n]),
                             ("Br", self.gains[:, scenario, n:])):
            for i in range(n):
                columns[f"{name}_{i + 1}"] = signal[:, i]
        return pd.DataFrame(columns)


class Simulator:
    """Batched simulator of a :class:`~teleopkit.scenarios.Scenario`.

    Parameters
    ----------
    scenario : Scenario
        Teleoperator, delay profiles and operator reference gains (``B`` scenarios).
    dt : float
        Integration step in seconds.
    control_period : float
        Period over which the remote gains are held, a multiple of ``dt``.
    backend : {"compiled", "reference"}
        The numba kernel or the readable numpy reference.

    Examples
    --------
    >>> from teleopkit.scenarios import paper_scenarios
    >>> sim = Simulator(paper_scenarios(0, batch=2))
    >>> result = sim.advance(np.tile([10.0, 10.0, 30.0, 30.0], (3, 2, 1)))
    >>> result.state.shape, round(sim.time, 6)
    ((3, 2, 16), 0.03)
    """

    def __init__(self, scenario: Scenario, dt: float = DEFAULT_DT, control_period: float = 0.01,
                 backend: Backend = "compiled") -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"integration step must be positive, got {dt}")
        substeps = round(control_period / dt)
        if substeps < 1 or abs(substeps * dt - control_period) > 1e-9 * control_period:
            raise ValueError(f"control period {control_period} must be a positive multiple of the "
                             f"integration step {dt}")
        if backend not in ("compiled", "reference"):
            raise ValueError(f"backend must be 'compiled' or 'reference', got {backend!r}")
        self.scenario = scenario
        self.dt = dt
        self.substeps = substeps
        self.control_period = control_period
        self.backend = backend
        self._model = _kernel.kernel_model(scenario.params)
        self.reset()

    @property
    def batch(self) -> int:
        """Number of scenarios."""
        return self.scenario.batch

    @property
    def n_joints(self) -> int:
        """Number of joints per arm."""
        return self.scenario.params.n_joints

    @property
    def time(self) -> float:
        """Current simulation time in seconds."""
        return self._step * self.dt

    @property
    def state(self) -> np.ndarray:
        """Current state, shape ``(B, 8 n)`` (a copy)."""
        return (self._reference.state if self._reference else self._x).copy()

    def initial_state(self) -> np.ndarray:
        """State at ``t = 0``: the scenario's initial positions, zero velocities and integrals."""
        init = self.scenario.params.initial
        zeros = np.zeros(self.n_joints)
        row = np.concatenate([init.local, zeros, init.remote, zeros, init.motor, zeros, zeros,
                              zeros])
        return np.tile(row, (self.batch, 1))

    def reset(self) -> None:
        """Return to ``t = 0`` with the initial state and an empty history."""
        self._step = 0
        x = self.initial_state()
        n = self.n_joints
        length = math.ceil(self.scenario.delay_bound / self.dt) + 2
        self._reference: ReferenceIntegrator | None = None
        if self.backend == "reference":
            self._reference = ReferenceIntegrator(self.scenario.params, x, self.dt,
                                                  self.substeps, self.scenario.delay_bound)
            return
        self._x = x
        self._initial = np.stack([x[:, :n], x[:, 4 * n:5 * n]], axis=1)
        self._hist = np.zeros((self.batch, 2, length, 2 * n))
        self._hist[..., :n] = self._initial[:, :, None, :]

    def _initial_row(self) -> StepResult:
        """The record at ``t = 0`` (the delayed signals are the constant past)."""
        x = self.initial_state()
        n = self.n_joints
        delays, _ = self.sample_inputs(np.zeros(1))
        delayed = np.stack([x[:, :n], x[:, 4 * n:5 * n]], axis=1)
        return StepResult(np.zeros(1), x[None], delayed[None], delays)

    def sample_inputs(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Delays ``(S, B, 2)`` and operator reference ``(S, B, n)`` at the times ``(S,)``.

        Parameters
        ----------
        times : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        delays : ndarray, shape (S, B, 2)
            ``T_l(t)`` and ``T_r(t)`` in seconds for each scenario.
        reference : ndarray, shape (S, B, n)
            Operator reference ``q_h(t)`` in radians, with each scenario's reference gains.
        """
        delays, unit = self._sample(times)
        return np.moveaxis(delays, 0, -1), self.scenario.reference_gains[None] * unit[:, None]

    def _sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Delays ``(2, S, B)`` and the operator reference with unit gains ``(S, n)`` at ``times``.

        The reference of scenario ``b`` is ``G_b`` times the unit one (see
        :class:`~teleopkit.params.Operator`), so it is evaluated once, not once per scenario.
        """
        delays = np.empty((2, times.size, self.batch))
        delays[0] = self.scenario.forward.sample(times)
        delays[1] = self.scenario.backward.sample(times)
        unit = self.scenario.params.operator.reference(times, np.ones((1, self.n_joints)))
        return delays, unit[:, 0]

    def advance(self, gains: np.ndarray) -> StepResult:
        """Simulate ``P`` control periods with the given remote gains.

        Parameters
        ----------
        gains : ndarray, shape (P, B, 2 n) or (B, 2 n) or (2 n,)
            Remote gains ``[K_r^1..K_r^n, B_r^1..B_r^n]`` held over each period; a 1-D or 2-D
            array is one period.

        Returns
        -------
        StepResult
            The state, delayed signals and delays at the end of each period.
        """
        gains = check_gains(gains, self.n_joints)
        gains = np.ascontiguousarray(np.broadcast_to(
            gains if gains.ndim == 3 else gains.reshape(1, -1, gains.shape[-1]),
            (gains.shape[0] if gains.ndim == 3 else 1, self.batch, 2 * self.n_joints)))
        periods = gains.shape[0]
        stages = self._step + 0.5 * np.arange(2 * periods * self.substeps + 1)
        delays, unit = self._sample(stages * self.dt)
        ends = slice(2 * self.substeps, None, 2 * self.substeps)
        end_delays = np.moveaxis(delays[:, ends], 0, -1).copy()
        reference_gains = self.scenario.reference_gains
        if self._reference is not None:
            state, delayed = self._reference.advance(np.moveaxis(delays, 0, -1),
                                                     reference_gains[None] * unit[:, None], gains)
        else:
            state = np.empty((periods, self.batch, 8 * self.n_joints))
            delayed = np.empty((periods, self.batch, 2, self.n_joints))
            delays /= self.dt  # the kernel takes them in steps
            _kernel.advance(self._x, self._hist, self._initial, self._step, self.dt,
                            self.substeps, delays, unit, reference_gains, gains, self._model,
                            state, delayed)
        self._step += periods * self.substeps
        return StepResult(stages[ends] * self.dt, state, delayed, end_delays)

    def run(self, duration: float, gains: np.ndarray | None = None,
            chunk: float = 1.0) -> Trajectory:
        """Reset and simulate ``duration`` seconds, recording every control period.

        Parameters
        ----------
        duration : float
            Length of the run in seconds (rounded to whole control periods).
        gains : ndarray, optional
            Remote gains: ``(2 n,)`` or ``(B, 2 n)`` constant, or ``(P, B, 2 n)`` one row per
            period; the scenario's ``remote_gains`` by default.
        chunk : float
            Seconds simulated per kernel call (bounds the memory of the sampled inputs).

        Returns
        -------
        Trajectory
            The run, from ``t = 0`` (initial row included).
        """
        if not (math.isfinite(duration) and duration > 0):
            raise ValueError(f"duration must be positive, got {duration}")
        periods = max(1, round(duration / self.control_period))
        if gains is None:
            gains = self.scenario.params.remote_gains.as_action()
        gains = check_gains(gains, self.n_joints)
        if gains.ndim < 3:
            gains = np.broadcast_to(gains, (periods, self.batch, gains.shape[-1]))
        if gains.shape[0] != periods:
            raise ValueError(f"gain schedule has {gains.shape[0]} periods, the run needs {periods}")
        self.reset()
        parts = [self._initial_row()]
        per_chunk = max(1, round(chunk / self.control_period))
        for start in range(0, periods, per_chunk):
            parts.append(self.advance(gains[start:start + per_chunk]))
        def joined(name: str) -> np.ndarray:
            return np.concatenate([getattr(part, name) for part in parts])

        return Trajectory(t=joined("t"), state=joined("state"), delayed=joined("delayed"),
                          delays=joined("delays"), gains=np.concatenate([gains[:1], gains]))


def simulate(gains: tuple[float, float] | np.ndarray | None = None, duration: float = 40.0,
             delay: str | tuple[DelayProfile, DelayProfile] = "paper", seed: int = 0,
             params: TeleoperatorParams | None = None, dt: float = DEFAULT_DT,
             control_period: float = 0.01) -> pd.DataFrame:
    """Simulate one scenario and return it as a table.

    Parameters
    ----------
    gains : (K_r, B_r) or ndarray, optional
        Uniform remote gains as a pair, or an action vector ``[K_r..., B_r...]``; the parameters'
        ``remote_gains`` by default.
    duration : float
        Length in seconds.
    delay : str or (DelayProfile, DelayProfile)
        A spec for :func:`teleopkit.delays.parse_delay` or the forward and backward profiles.
    seed : int
        Seed of the operator's reference gains and of random delay parameters.
    params : TeleoperatorParams, optional
        The teleoperator; the paper's by default.
    dt : float
        Integration step.
    control_period : float
        Gain hold period.

    Returns
    -------
    pandas.DataFrame
        Columns ``t, ql_i, dql_i, qr_i, dqr_i, theta_i, dtheta_i, Tl, Tr, ql_delayed_i,
        theta_delayed_i, e_track_i, e_damp_i, Kr_i, Br_i`` every control period.

    Examples
    --------
    >>> table = simulate((10.0, 30.0), duration=1.0, delay="constant:0.2")
    >>> len(table), float(table["t"].iloc[-1])
    (101, 1.0)
    """
    params = params if params is not None else paper_setup()
    rng = np.random.default_rng(seed)
    reference = sample_reference_gains(rng, 1, params.n_joints)
    forward, backward = parse_delay(delay, rng) if isinstance(delay, str) else delay
    action = None
    if gains is not None:
        gains = np.asarray(gains, dtype=float)
        action = np.repeat(gains, params.n_joints) if gains.shape == (2,) else gains
    sim = Simulator(Scenario(params, forward, backward, reference), dt, control_period)
    return sim.run(duration, action).to_frame()
