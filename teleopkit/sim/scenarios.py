"""Scenarios: a teleoperator, its two delay profiles, the operator's motions and the starts.

:func:`paper_scenarios` draws the randomisation of the authors' simulation model: reference
gains ``G_i`` uniform on ``[-1, -0.5] U [0.5, 1]`` and delay scales ``g_m, g_s ~ U[0.5, 1]``.
A :class:`~teleopkit.setup.Setup` draws batches of other distributions (operator motions,
starts, delays and plants per scenario).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from teleopkit.delays.combinators import StackedDelay
from teleopkit.delays.paper_fit import PAPER_DELAY_MAX, PAPER_DELAY_MIN
from teleopkit.delays.profiles import ConstantDelay, DelayProfile, FourierDelay
from teleopkit.model.params import TeleoperatorParams, paper_setup
from teleopkit.sim.motions import Motion, SineMotion

__all__ = ["PAPER_DELAY_BOUND", "PAPER_DELAY_FLOOR", "PAPER_SCALES", "Scenario", "generator",
           "paper_scenarios", "sample_reference_gains"]

PAPER_SCALES = (0.5, 1.0)
"""Range of the per-episode delay scales ``g_m, g_s`` of :func:`paper_scenarios`."""

PAPER_DELAY_BOUND = PAPER_SCALES[1]
"""Largest delay of :func:`paper_scenarios` in seconds: the scale times the Fourier profile,
which :class:`~teleopkit.delays.profiles.FourierDelay` keeps within 1 s."""

PAPER_DELAY_FLOOR = PAPER_SCALES[0] * PAPER_DELAY_MIN / PAPER_DELAY_MAX
"""Smallest delay of :func:`paper_scenarios` in seconds (about 0.451 s): the smallest scale
times the Fourier profile's rigorous minimum. A certificate for delays from at most this
minimum covers the paper's scenarios."""


@dataclass(frozen=True)
class Scenario:
    """A batch of ``B`` scenarios sharing one teleoperator.

    The operator reference of scenario ``b`` is ``reference_gains[b]`` times column ``b`` of
    ``motion`` (its only column when the batch shares one motion).

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.
    forward : DelayProfile
        Local-to-remote delay ``T_l(t)`` (batch 1 or ``B``).
    backward : DelayProfile
        Remote-to-local delay ``T_r(t)`` (batch 1 or ``B``).
    reference_gains : ndarray, shape (B, n)
        Operator reference gains ``G`` of each scenario.
    motion : Motion, optional
        Operator reference motion (1 or ``B`` columns); by default the sines of
        ``params.operator``.
    start : ndarray, shape (B, 3, n) or (1, 3, n), optional
        Initial positions ``q_l(0), q_r(0), theta_r(0)`` of each scenario (or shared); by
        default ``params.initial``. Velocities start at zero and the past is held constant.
    other_plants : tuple of TeleoperatorParams, optional
        Further plants (arms, joints, local gains, operator spring and damper, environment,
        torque limit) some scenarios run, with as many joints as ``params``.
    plant_index : ndarray of int, shape (B,), optional
        Which of :attr:`plants` (``params``, then ``other_plants``) each scenario runs; by
        default ``params``.
    """

    params: TeleoperatorParams = field(default_factory=paper_setup)
    forward: DelayProfile = field(default_factory=ConstantDelay)
    backward: DelayProfile = field(default_factory=ConstantDelay)
    reference_gains: np.ndarray = field(default_factory=lambda: np.ones((1, 2)))
    motion: Motion | None = None
    start: np.ndarray | None = None
    other_plants: tuple[TeleoperatorParams, ...] = ()
    plant_index: np.ndarray | None = None

    def __post_init__(self) -> None:
        gains = np.atleast_2d(np.asarray(self.reference_gains, dtype=float))
        if gains.ndim != 2 or gains.shape[1] != self.params.n_joints:
            raise ValueError(f"reference gains need shape (batch, {self.params.n_joints}), "
                             f"got {gains.shape}")
        if not np.all(np.isfinite(gains)):
            raise ValueError("reference gains must be finite")
        object.__setattr__(self, "reference_gains", gains)
        self._check_motion()
        self._check_start()
        self._check_plants()
        for name in ("forward", "backward"):
            profile = getattr(self, name)
            bound = profile.bound
            if not np.isfinite(bound) or bound < 0:
                raise ValueError(f"{name} delay bound must be finite and >= 0, got {bound}")
            columns = np.shape(profile.sample(np.zeros(1)))[-1]
            if columns not in (1, gains.shape[0]):
                raise ValueError(f"the {name} delay profile has {columns} scenarios, the "
                                 f"reference gains {gains.shape[0]}: give it 1 or the same")

    def _check_motion(self) -> None:
        motion = self.motion
        if motion is None:
            object.__setattr__(self, "motion", SineMotion.from_operator(self.params.operator))
            return
        if not isinstance(motion, Motion):
            raise ValueError(f"motion must be a Motion (columns, n_joints, sample), got {motion!r}")
        n, batch = self.params.n_joints, self.reference_gains.shape[0]
        if motion.n_joints != n:
            raise ValueError(f"the operator motion moves {motion.n_joints} joints, the arm has {n}")
        if motion.columns not in (1, batch):
            raise ValueError(f"the operator motion has {motion.columns} scenarios, the reference "
                             f"gains {batch}: give it 1 or the same")

    def _check_start(self) -> None:
        n, batch = self.params.n_joints, self.reference_gains.shape[0]
        if self.start is None:
            initial = self.params.initial
            start = np.array([[initial.local, initial.remote, initial.motor]], dtype=float)
        else:
            start = np.asarray(self.start, dtype=float)
        if start.ndim != 3 or start.shape[1:] != (3, n) or start.shape[0] not in (1, batch):
            raise ValueError(f"start needs shape ({batch} or 1, 3, {n}) (q_l, q_r, theta_r), "
                             f"got {start.shape}")
        if not np.all(np.isfinite(start)):
            raise ValueError("start positions must be finite")
        object.__setattr__(self, "start", start)

    def _check_plants(self) -> None:
        object.__setattr__(self, "other_plants", tuple(self.other_plants))
        plants = self.plants
        for params in plants:
            if not isinstance(params, TeleoperatorParams):
                raise ValueError(f"plants must be TeleoperatorParams, got {params!r}")
            if params.n_joints != self.params.n_joints:
                raise ValueError(f"every plant needs {self.params.n_joints} joints, one has "
                                 f"{params.n_joints}")
        if self.plant_index is None:
            return
        index = np.asarray(self.plant_index)
        if index.shape != (self.batch,) or not np.issubdtype(index.dtype, np.integer) or (
                index.size and (index.min() < 0 or index.max() >= len(plants))):
            raise ValueError(f"plant_index needs {self.batch} whole numbers in 0..{len(plants) - 1}"
                             f", got {self.plant_index!r}")
        object.__setattr__(self, "plant_index", index.astype(np.intp))

    @property
    def plant_of(self) -> np.ndarray:
        """The index in :attr:`plants` of each scenario's plant, ``(B,)``."""
        if self.plant_index is None:
            return np.zeros(self.batch, dtype=np.intp)
        return self.plant_index

    @property
    def plants(self) -> tuple[TeleoperatorParams, ...]:
        """Every plant of the batch: ``params``, then :attr:`other_plants`."""
        return (self.params, *self.other_plants)

    @property
    def lanes_by_plant(self) -> list[tuple[TeleoperatorParams, np.ndarray]]:
        """Each plant the batch runs with the scenarios that run it (ascending indices)."""
        index = self.plant_of
        return [(params, np.flatnonzero(index == k)) for k, params in enumerate(self.plants)
                if np.any(index == k)]

    def per_plant(self, function: Callable[[TeleoperatorParams, np.ndarray], np.ndarray],
                  values: np.ndarray) -> np.ndarray:
        """Evaluate ``function(plant, values of its scenarios)`` for each plant of the batch.

        Parameters
        ----------
        function : callable
            A function of a plant and an array whose first axis is scenarios (for example
            :func:`~teleopkit.sim.energy.remote_energy` of states), returning an array with the
            same first axis.
        values : ndarray, shape (B, ...)
            One entry per scenario.

        Returns
        -------
        ndarray, shape (B, ...)
            Scenario ``b``'s entry computed with its plant.
        """
        if len(self.plants) == 1:
            return function(self.params, values)
        parts = [(lanes, function(params, values[lanes])) for params, lanes in
                 self.lanes_by_plant]
        out = np.empty((self.batch, *parts[0][1].shape[1:]), dtype=parts[0][1].dtype)
        for lanes, part in parts:
            out[lanes] = part
        return out

    @property
    def batch(self) -> int:
        """Number of scenarios."""
        return self.reference_gains.shape[0]

    @property
    def starts(self) -> np.ndarray:
        """Initial positions ``(B, 3, n)``: ``q_l(0), q_r(0), theta_r(0)`` of each scenario."""
        start = cast(np.ndarray, self.start)  # set in __post_init__
        return np.broadcast_to(start, (self.batch, *start.shape[1:]))

    @property
    def reference_motion(self) -> Motion:
        """The operator motion (``motion``, or the sines of ``params.operator``)."""
        return cast(Motion, self.motion)  # set in __post_init__

    def repeat(self, times: int) -> Scenario:
        """The batch repeated ``times`` times along the batch axis (one copy per candidate).

        Shared delay profiles and motions stay shared; per-scenario ones are repeated (the
        paper's and constant delays keep their factored form, others are stacked).

        Parameters
        ----------
        times : int
            Copies.

        Returns
        -------
        Scenario
            ``times * batch`` scenarios, copy ``c`` of scenario ``b`` at ``c * batch + b``.
        """
        motion = self.motion
        if motion is not None and motion.columns > 1:
            if not isinstance(motion, SineMotion):
                raise ValueError(f"cannot repeat a motion of type {type(motion).__name__}")
            motion = SineMotion(*(np.tile(getattr(motion, name), (times, 1, 1)) for name in (
                "amplitudes", "frequencies", "phases", "decays")))
        start = self.start if self.start is None or len(self.start) == 1 else np.tile(
            self.start, (times, 1, 1))
        return Scenario(self.params, _repeat_delay(self.forward, self.batch, times),
                        _repeat_delay(self.backward, self.batch, times),
                        np.tile(self.reference_gains, (times, 1)), motion, start,
                        self.other_plants,
                        None if self.plant_index is None else np.tile(self.plant_index, times))

    @property
    def delay_bound(self) -> float:
        """Largest delay of either channel."""
        return max(self.forward.bound, self.backward.bound)


def _repeat_delay(profile: DelayProfile, batch: int, times: int) -> DelayProfile:
    """A profile of ``batch`` scenarios (or one shared) repeated ``times`` times."""
    if np.shape(profile.sample(np.zeros(1)))[-1] == 1:
        return profile
    if isinstance(profile, FourierDelay):
        return FourierDelay(np.tile(profile.scale, times), profile.bound)
    if isinstance(profile, ConstantDelay):
        return ConstantDelay(np.tile(profile.value, times), profile.bound)
    return StackedDelay((profile,) * times)


def sample_reference_gains(rng: np.random.Generator, batch: int, n_joints: int = 2) -> np.ndarray:
    """Draw reference gains uniformly on ``[-1, -0.5] U [0.5, 1]``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the magnitudes and signs.
    batch : int
        Number of scenarios.
    n_joints : int
        Number of joints.

    Returns
    -------
    ndarray, shape (batch, n_joints)
        Operator reference gains ``G``: magnitudes from ``U[0.5, 1]``, each sign negative with
        probability 1/2.
    """
    magnitude = rng.uniform(0.5, 1.0, size=(batch, n_joints))
    return np.where(rng.random((batch, n_joints)) < 0.5, -magnitude, magnitude)


def generator(seed: np.random.Generator | int) -> np.random.Generator:
    """``seed`` if it is a generator, else one seeded by it.

    Parameters
    ----------
    seed : numpy.random.Generator or int
        A generator, or a non-negative integer.

    Returns
    -------
    numpy.random.Generator
        The generator.

    Raises
    ------
    TypeError
        If ``seed`` is neither (a bool is not a seed).
    ValueError
        If it is a negative integer.
    """
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise TypeError(f"seed must be a non-negative integer or a numpy Generator, got "
                        f"{type(seed).__name__}")
    if seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    return np.random.default_rng(seed)


def paper_scenarios(rng: np.random.Generator | int = 0, batch: int = 1,
                    params: TeleoperatorParams | None = None) -> Scenario:
    """Draw ``batch`` scenarios with the paper's randomisation.

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Generator or seed.
    batch : int
        Number of scenarios.
    params : TeleoperatorParams, optional
        Teleoperator; the paper's by default.

    Returns
    -------
    Scenario
        Fourier delays scaled by ``U[0.5, 1]`` per channel and random reference gains.

    Examples
    --------
    >>> scenario = paper_scenarios(0, batch=4)
    >>> scenario.batch, bool(round(scenario.delay_bound, 3) <= 1.001)
    (4, True)
    """
    if isinstance(batch, bool) or not isinstance(batch, int | np.integer) or batch < 1:
        raise ValueError(f"batch must be a whole number of scenarios >= 1, got {batch!r}")
    rng = generator(rng)
    params = params if params is not None else paper_setup()
    reference = sample_reference_gains(rng, batch, params.n_joints)
    scales = rng.uniform(*PAPER_SCALES, size=(2, batch))
    return Scenario(params, FourierDelay(scales[0]), FourierDelay(scales[1]), reference)
