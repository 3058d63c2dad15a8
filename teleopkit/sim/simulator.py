"""Batched fixed-step simulator of the delayed teleoperator.

The remote gains are held over each control period (10 ms by default) and the model is integrated
at a fixed step (:data:`~teleopkit.sim.timing.DEFAULT_DT`, 2.5 ms, by default) with Butcher's
fifth-order Runge–Kutta method (:mod:`teleopkit.sim.tableau`). Delays and the operator reference
are sampled at every stage time (quarter steps) in numpy; the compiled kernel
(``backend="compiled"``, :mod:`teleopkit.sim.kernel`) or the readable numpy integrator
(``backend="numpy"``, :mod:`teleopkit.sim.numpy_integrator`) integrates. A batch of scenarios
shares the model; the batch axis comes first in every array.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Literal, Protocol, cast

import numpy as np

from teleopkit.delays.jumps import has_jumps, sample_left
from teleopkit.delays.profiles import DelayProfile
from teleopkit.delays.spec import check_duration
from teleopkit.model.params import TeleoperatorParams
from teleopkit.sim.backends import Backend, CompiledBackend, NumpyBackend, constant_past
from teleopkit.sim.divergence import Divergence, DivergenceWarning
from teleopkit.sim.memory import check_fits
from teleopkit.sim.motions import check_motion_ends
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.stability import check_motor_damping, check_step
from teleopkit.sim.state import StateLayout
from teleopkit.sim.tableau import ROWS_PER_STEP
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT, substeps
from teleopkit.sim.timing import periods as whole_periods
from teleopkit.sim.trajectory import StepResult, Trajectory

__all__ = ["CALL_VALUES", "LOOKAHEAD_VALUES", "Simulator", "check_gains", "simulate",
           "simulate_trajectory"]

LOOKAHEAD_VALUES = 16384
"""Delay values per channel :class:`Simulator` samples ahead of a short advance: 10 s of one
scenario at the default step (some 0.7 MB of inputs), a period or two of a large batch whose
delay profiles have no ``factors`` (with factors the batch shares one column: 10 s)."""

CALL_VALUES = 1 << 20
"""Delay values per channel that one kernel call of :meth:`Simulator.run` samples by default
(16 MB of inputs for both channels): a run of up to 655 s with profiles that have ``factors``, a
40 s run of one scenario otherwise, or 16 periods of a batch of 4096. Long calls are faster
(each block of scenarios reads history its thread has just written) until their inputs stop
fitting in memory already touched (measured in ``docs/benchmark_history.md``)."""

if TYPE_CHECKING:
    import pandas as pd

    from teleopkit.setup import Setup

BackendName = Literal["compiled", "numpy"]


class _Factored(Protocol):
    def factors(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def check_gains(gains: np.ndarray, n_joints: int, batch: int | None = None) -> np.ndarray:
    """Validate remote gains ``[K_r, B_r]`` (finite, non-negative, last axis ``2 n``).

    Parameters
    ----------
    gains : ndarray, shape (..., 2 n)
        Gains to check.
    n_joints : int
        Number of joints.
    batch : int, optional
        Scenarios ``B`` the gains are for: then their shape must be ``(2 n,)``, ``(B, 2 n)`` or
        ``(P, B, 2 n)`` (``1`` in place of ``B`` is shared by the batch).

    Returns
    -------
    ndarray
        The gains as a float array.
    """
    gains = np.asarray(gains, dtype=float)
    width = 2 * n_joints
    if gains.shape[-1:] != (width,):
        raise ValueError(f"remote gains need {width} values [K_r..., B_r...] on the last "
                         f"axis, got shape {gains.shape}")
    if batch is not None and (gains.ndim > 3 or gains.shape[-2:-1] not in ((), (1,), (batch,))):
        raise ValueError(f"remote gains need shape ({width},), (B, {width}) or (periods, B, "
                         f"{width}) with B = {batch} scenarios (or 1), got {gains.shape}")
    # min and max propagate NaN: one test each covers NaN, inf and negative values
    if gains.size and not (gains.min() >= 0 and gains.max() < math.inf):
        raise ValueError("remote gains must be finite and non-negative")
    return gains


class Simulator:
    """Batched simulator of a :class:`~teleopkit.sim.scenarios.Scenario`.

    Parameters
    ----------
    scenario : Scenario
        Teleoperator, delay profiles and operator reference gains (``B`` scenarios).
    dt : float
        Integration step in seconds, inside the method's stability limit for the model's
        damping (:mod:`teleopkit.sim.stability`; a longer step raises ``ValueError``).
    control_period : float
        Period over which the remote gains are held, a multiple of ``dt``.
    backend : {"compiled", "numpy"}
        The numba kernel or the readable numpy integrator.

    Attributes
    ----------
    batch : int
        Number of scenarios ``B``.
    n_joints : int
        Number of joints per arm.

    Examples
    --------
    >>> from teleopkit.sim.scenarios import paper_scenarios
    >>> sim = Simulator(paper_scenarios(0, batch=2))
    >>> result = sim.advance(np.tile([10.0, 10.0, 30.0, 30.0], (3, 2, 1)))
    >>> result.state.shape, round(sim.time, 6)
    ((3, 2, 24), 0.03)
    """

    def __init__(self, scenario: Scenario, dt: float = DEFAULT_DT,
                 control_period: float = CONTROL_PERIOD, backend: BackendName = "compiled") -> None:
        if not isinstance(scenario, Scenario):
            raise TypeError(f"scenario must be a Scenario (paper_scenarios(seed, batch) or "
                            f"Setup.scenarios(seed, batch)), got {type(scenario).__name__}")
        self.substeps = substeps(control_period, dt)
        if backend not in ("compiled", "numpy"):
            raise ValueError(f"backend must be 'compiled' or 'numpy', got {backend!r}")
        for params in scenario.plants:
            check_step(params, dt, control_period)
        # the motor damping a step integrates stably scales with the smallest rotor inertia
        self._lightest_rotors = min(scenario.plants, key=lambda p: min(p.joints.rotor_inertia))
        self.scenario = scenario
        self.batch = scenario.batch
        self.n_joints = scenario.params.n_joints
        channels = (scenario.forward, scenario.backward)
        # delays that jump are read at their left limits by each step's last stage
        self._jumps = any(has_jumps(p) for p in channels)
        # the kernel reads one shape of time per channel when both profiles have factors
        self._factored = not self._jumps and all(hasattr(p, "factors") for p in channels)
        self.dt = dt
        self.control_period = control_period
        self.backend = backend
        self.layout = StateLayout(scenario.params.n_joints)
        self._inputs: _Inputs | None = None
        self.reset()

    def _checked(self, gains: np.ndarray) -> np.ndarray:
        """:func:`check_gains` for the batch, and motor damping the step integrates stably."""
        gains = check_gains(gains, self.n_joints, self.batch)
        if gains.size:
            check_motor_damping(self._lightest_rotors, self.dt, gains[..., self.n_joints:].max(),
                                "remote damping B_r", self.control_period)
        return gains

    @property
    def _delay_columns(self) -> int:
        """Columns of sampled delays per channel: one shared by the batch, or one per scenario."""
        return 1 if self._factored else self.batch

    @property
    def _input_columns(self) -> int:
        """Columns of sampled inputs: the delays' or the operator motion's, the larger."""
        return max(self._delay_columns, self.scenario.reference_motion.columns)

    @property
    def time(self) -> float:
        """Current simulation time in seconds."""
        return self._step * self.dt

    @property
    def state(self) -> np.ndarray:
        """Current state, shape ``(B, 12 n)`` (a copy)."""
        return self._backend.state.copy()

    @property
    def state_bytes(self) -> int:
        """Memory of the integration state (states and channel histories) in bytes."""
        return self._backend.nbytes

    def initial_state(self) -> np.ndarray:
        """State at ``t = 0``: the scenarios' initial positions, zero velocities and integrals."""
        starts = self.scenario.starts
        return self.layout.pack(self.batch, ql=starts[:, 0], qr=starts[:, 1], theta=starts[:, 2])

    def reset(self) -> None:
        """Return to ``t = 0`` with the initial state and an empty history."""
        self._step = 0
        kind = NumpyBackend if self.backend == "numpy" else CompiledBackend
        self._backend: Backend = kind(self.scenario, self.initial_state(), self.dt,
                                      self.substeps, self.scenario.delay_bound)

    def initial_record(self) -> StepResult:
        """The record at ``t = 0`` (the delayed signals are the constant past)."""
        x = self.initial_state()
        delays, _ = self.sample_inputs(np.zeros(1))
        return StepResult(np.zeros(1), x[None], constant_past(x)[None], delays)

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
        delays, scale, unit = self._sample(times)
        return ((delays * scale).transpose(0, 2, 1),
                self.scenario.reference_gains[None] * unit)

    def _sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Delays in the kernel's factors at ``times`` and the operator reference with unit gains.

        Shapes ``(S, 2, K)``, ``(2, B)`` and ``(S, M, n)``: when both channels' profiles have
        ``factors``, one shape of time per channel (``K = 1``) and each scenario's scale,
        else one column per scenario (``K = B``) and ones (:func:`~teleopkit.sim.kernel.advance`).
        The reference of scenario ``b`` is ``G_b`` times its column of the motion (``M = 1``
        when the batch shares one motion: it is evaluated once, not once per scenario).
        """
        channels = (self.scenario.forward, self.scenario.backward)
        delays = np.empty((times.size, 2, self._delay_columns))
        scale = np.ones((2, self.batch))
        for c, profile in enumerate(channels):
            if self._factored:
                delays[:, c, 0], scale[c] = cast(_Factored, profile).factors(times)
            else:
                delays[:, c] = profile.sample(times)
        return delays, scale, self.scenario.reference_motion.sample(times)

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
        gains = self._checked(gains)
        if gains.ndim != 3:
            gains = gains.reshape(1, -1, gains.shape[-1])
        shape = (gains.shape[0], self.batch, gains.shape[2])
        if gains.shape != shape:
            gains = np.broadcast_to(gains, shape)
        result = self._empty_record(gains.shape[0])
        self._integrate(gains, result)
        return result

    def _stage_inputs(self, periods: int) -> _Inputs:
        """Times, delays and their scales, left limits and unit reference at the stage times.

        Shapes ``(S,)``, ``(S, 2, K)``, ``(2, B)``, ``(P substeps, 2, K)`` (empty for continuous
        delays) and ``(S, M, n)`` (see :meth:`_sample`): every quarter step
        (:data:`~teleopkit.sim.tableau.ROWS_PER_STEP`) of the next ``periods`` periods,
        ``S = 4 P substeps + 1``, and the end of each of their steps.

        The inputs are functions of time alone, so they are sampled ahead, up to
        :data:`LOOKAHEAD_VALUES` delay values, and sliced by later calls: a control period of
        one scenario would otherwise spend most of its time in the per-call cost of sampling.
        A profile that cannot be sampled that far ahead (one that raises past some time) is
        sampled as needed, so that its error comes when the run reaches that time.
        """
        rows = ROWS_PER_STEP * periods * self.substeps + 1
        cached = self._inputs
        if cached is None or not cached.covers(self.scenario, self._step, rows):
            ahead = max(rows, LOOKAHEAD_VALUES // self._input_columns)
            try:
                cached = self._sample_from_here(ahead)
            except ValueError:
                cached = self._sample_from_here(rows)
            self._inputs = cached
        first = self._step - cached.step
        window = slice(ROWS_PER_STEP * first, ROWS_PER_STEP * first + rows)
        steps = slice(first, first + periods * self.substeps)
        return _Inputs(self.scenario, self._step, cached.times[window], cached.delays[window],
                       cached.scale, cached.left[steps], cached.unit[window])

    def _sample_from_here(self, rows: int) -> _Inputs:
        """The inputs at ``rows`` stage times (quarter steps) from the current step."""
        times = (self._step + np.arange(rows) / ROWS_PER_STEP) * self.dt
        delays, scale, unit = self._sample(times)
        return _Inputs(self.scenario, self._step, times, delays, scale, self._sample_left(times),
                       unit)

    def _sample_left(self, times: np.ndarray) -> np.ndarray:
        """Left limits ``(S // 4, 2, K)`` of jumping delays at the step ends among ``times``.

        See :mod:`teleopkit.delays.jumps`; continuous delays have none, ``(0, 2, K)``.
        """
        ends = times[ROWS_PER_STEP::ROWS_PER_STEP] if self._jumps else times[:0]
        left = np.empty((ends.size, 2, self._delay_columns))
        if self._jumps:
            for c, profile in enumerate((self.scenario.forward, self.scenario.backward)):
                left[:, c] = sample_left(profile, ends)
        return left

    def _empty_record(self, periods: int) -> StepResult:
        """Uninitialised arrays for ``periods`` recorded times."""
        return StepResult(np.empty(periods), np.empty((periods, self.batch, self.layout.size)),
                          np.empty((periods, self.batch, 2, self.n_joints)),
                          np.empty((periods, self.batch, 2)))

    def _integrate(self, gains: np.ndarray, out: StepResult) -> None:
        """Simulate ``gains.shape[0]`` periods of checked gains ``(P, B, 2 n)`` into ``out``."""
        periods = gains.shape[0]
        inputs = self._stage_inputs(periods)
        scale = inputs.scale
        ends = slice(ROWS_PER_STEP * self.substeps, None, ROWS_PER_STEP * self.substeps)
        out.t[:] = inputs.times[ends]
        np.multiply(inputs.delays[ends], scale, out=out.delays.transpose(0, 2, 1))
        self._backend.advance(self._step, inputs.delays, scale, inputs.left, inputs.unit,
                              self.scenario.reference_gains, gains, out.state, out.delayed)
        self._step += periods * self.substeps

    def record_bytes(self, periods: int) -> int:
        """Memory a :meth:`run` of ``periods`` control periods records, in bytes.

        Parameters
        ----------
        periods : int
            Control periods.

        Returns
        -------
        int
            States, delayed signals, delays and gains of every recorded time.
        """
        n = self.n_joints
        return 8 * (periods + 1) * self.batch * (self.layout.size + 2 * n + 2 + 2 * n)

    def _periods_per_call(self, chunk: float | None) -> int:
        """Whole periods per kernel call of :meth:`run` (``chunk`` seconds, or the default)."""
        if chunk is None:
            return max(1, CALL_VALUES // (ROWS_PER_STEP * self.substeps * self._input_columns))
        if not (math.isfinite(chunk) and chunk > 0):
            raise ValueError(f"chunk must be a positive number of seconds, got {chunk}")
        return max(1, round(chunk / self.control_period))

    def run(self, duration: float, gains: np.ndarray | None = None,
            chunk: float | None = None) -> Trajectory:
        """Reset and simulate ``duration`` seconds, recording every control period.

        Parameters
        ----------
        duration : float
            Length of the run in seconds, a whole number of control periods.
        gains : ndarray, optional
            Remote gains: ``(2 n,)`` or ``(B, 2 n)`` constant, or ``(P, B, 2 n)`` one row per
            period; the scenario's ``remote_gains`` by default.
        chunk : float, optional
            Seconds simulated per kernel call, which bounds the memory of the sampled inputs;
            by default as many whole periods as sample about :data:`CALL_VALUES` delay values
            per channel (at least one period).

        Returns
        -------
        Trajectory
            The run, from ``t = 0`` (initial row included).

        Raises
        ------
        ValueError
            If ``duration`` is not a whole number of periods, ``chunk`` is not positive, the
            gains are negative, not finite, of the wrong shape or with a damping ``B_r`` the step
            cannot integrate stably, or the record would not fit in memory.
        """
        periods = whole_periods(duration, self.control_period)
        per_call = self._periods_per_call(chunk)
        check_fits(self.record_bytes(periods),
                   f"a run of {periods * self.control_period:g} s of {self.batch} scenario(s)")
        if gains is None:
            gains = self.scenario.params.remote_gains.as_action()
        gains = self._checked(gains)
        constant = gains.ndim < 3
        if constant:
            gains = np.broadcast_to(gains, (periods, self.batch, gains.shape[-1]))
        if gains.shape[0] != periods:
            raise ValueError(f"gain schedule has {gains.shape[0]} periods, the run needs {periods}")
        self.reset()
        record = self._empty_record(periods + 1)  # filled in place: no copies of the run
        first, initial = record.rows(slice(0, 1)), self.initial_record()
        for field in fields(StepResult):
            getattr(first, field.name)[:] = getattr(initial, field.name)
        for start in range(0, periods, per_call):
            stop = min(start + per_call, periods)
            self._integrate(gains[start:stop], record.rows(slice(1 + start, 1 + stop)))
        in_force = (np.broadcast_to(gains[:1], (periods + 1, *gains.shape[1:])) if constant
                    else np.concatenate([gains[:1], gains]))
        return Trajectory(record.t, record.state, record.delayed, record.delays, in_force)


@dataclass(frozen=True)
class _Inputs:
    """Delays and operator reference sampled at the stage times from grid step ``step`` on."""

    scenario: Scenario
    step: int
    times: np.ndarray
    delays: np.ndarray
    scale: np.ndarray
    left: np.ndarray
    unit: np.ndarray

    def covers(self, scenario: Scenario, step: int, rows: int) -> bool:
        """Whether these are ``scenario``'s inputs for ``rows`` stage times from ``step``."""
        return (scenario is self.scenario and step >= self.step
                and ROWS_PER_STEP * (step - self.step) + rows <= self.times.size)


def simulate_trajectory(gains: tuple[float, float] | np.ndarray | None = None,
                        duration: float = 40.0,
                        delay: str | float | tuple[DelayProfile, DelayProfile] | None = None,
                        seed: int = 0,
                        params: TeleoperatorParams | None = None, dt: float = DEFAULT_DT,
                        control_period: float = CONTROL_PERIOD,
                        setup: Setup | None = None) -> Trajectory:
    """Simulate one scenario; the arguments of :func:`simulate`, the run as a trajectory.

    Parameters
    ----------
    gains : (K_r, B_r) or ndarray, optional
        Uniform remote gains as a pair, or an action vector ``[K_r..., B_r...]``; the parameters'
        ``remote_gains`` by default.
    duration : float
        Length in seconds.
    delay : str, float or (DelayProfile, DelayProfile), optional
        A spec for :func:`teleopkit.delays.parse_delay`, a constant delay in seconds, or the
        forward and backward profiles; by default the setup's network.
    seed : int
        Seed of the operator's motion, the delays and the start (what the setup draws).
    params : TeleoperatorParams, optional
        The teleoperator, with the paper's network and operator draws (give ``params`` or
        ``setup``, not both).
    dt : float
        Integration step.
    control_period : float
        Gain hold period.
    setup : Setup, optional
        Plant, network, operator and start (:class:`~teleopkit.setup.Setup`); the paper's by
        default.

    Returns
    -------
    Trajectory
        The run of one scenario.

    Raises
    ------
    ValueError
        On bad input, including delays as long as the run (a number meant in milliseconds), a
        delay trace or a recorded operator motion that ends before the run does, and a step the
        model's damping or springs (a stiff wall) make unstable (:mod:`teleopkit.sim.stability`).
    TypeError
        If ``setup`` is not a :class:`~teleopkit.setup.Setup`, ``params`` not a
        :class:`~teleopkit.model.params.TeleoperatorParams` or the seed not an integer.

    Warns
    -----
    DivergenceWarning
        If the run diverged: its state stopped being finite or a position left the divergence
        radius (:meth:`~teleopkit.sim.divergence.Divergence.describe` names the time; the
        trajectory is returned as it is, and
        :meth:`~teleopkit.sim.trajectory.Trajectory.diverged_at` tells it too).
    """
    from teleopkit.setup import Setup

    if params is not None and setup is not None:
        raise ValueError("give params or setup, not both")
    if setup is not None and not isinstance(setup, Setup):
        raise TypeError(f"setup must be a Setup (Setup.paper() or Setup.from_file(path)), got "
                        f"{type(setup).__name__}")
    setup = setup if setup is not None else (
        Setup.from_params(params) if params is not None else Setup.paper())
    scenario = setup.scenarios(seed, 1, delay)
    whole_periods(duration, control_period)
    check_duration((scenario.forward, scenario.backward), duration)
    check_motion_ends(scenario.reference_motion, duration)
    action = None
    if gains is not None:
        gains = np.asarray(gains, dtype=float)
        action = np.repeat(gains, setup.n_joints) if gains.shape == (2,) else gains
    trajectory = Simulator(scenario, dt, control_period).run(duration, action)
    diverged = Divergence().describe(trajectory.t, trajectory.state)
    if diverged is not None:
        warnings.warn(diverged, DivergenceWarning, stacklevel=2)
    return trajectory


def simulate(gains: tuple[float, float] | np.ndarray | None = None, duration: float = 40.0,
             delay: str | float | tuple[DelayProfile, DelayProfile] | None = None, seed: int = 0,
             params: TeleoperatorParams | None = None, dt: float = DEFAULT_DT,
             control_period: float = CONTROL_PERIOD, setup: Setup | None = None,
             ) -> pd.DataFrame:
    """Simulate one scenario and return it as a table.

    Parameters
    ----------
    gains, duration, delay, seed, params, dt, control_period, setup
        As for :func:`simulate_trajectory`.

    Returns
    -------
    pandas.DataFrame
        Columns ``t, ql_i, dql_i, qr_i, dqr_i, theta_i, dtheta_i, Tl, Tr, ql_delayed_i,
        theta_delayed_i, e_track_i, e_damp_i, Kr_i, Br_i`` every control period.

    Raises
    ------
    ValueError
        As :func:`simulate_trajectory`.
    TypeError
        As :func:`simulate_trajectory`.

    Warns
    -----
    DivergenceWarning
        As :func:`simulate_trajectory`: the run diverged (the table shows it as it is).

    Examples
    --------
    >>> table = simulate((10.0, 30.0), duration=1.0, delay="constant:0.2")
    >>> len(table), float(table["t"].iloc[-1])
    (101, 1.0)
    """
    return simulate_trajectory(gains, duration, delay, seed, params, dt, control_period,
                               setup).to_frame()
