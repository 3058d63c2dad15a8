"""Time-varying communication delay profiles.

A profile is a frozen dataclass with a declared upper bound ``bound`` (seconds) and a method
``sample(t)`` returning the delay at the times ``t`` for each scenario of a batch: shape ``(S, B)``,
where ``B`` is the profile's own batch size (1 when it is the same for every scenario, and then it
broadcasts). ``sample`` checks that every value lies in ``[0, bound]`` and is finite, so a profile
can never exceed the bound that the certificate and the channel buffers were sized for. A
profile that is one shape of time times a scale per scenario (:class:`FourierDelay`,
:class:`ConstantDelay`) also offers ``factors(t)``, the two factors of ``sample(t)``: a large
batch then samples ``S`` values instead of ``S B``.

Profiles: :class:`FourierDelay` (the paper's Fig. 3), :class:`ConstantDelay`,
:class:`SinusoidalDelay`, :class:`SwitchingDelay` (bounded random, including fast adversarial
switching between the extremes) and :class:`TraceDelay` (a recorded trace, e.g. from CSV).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

from teleopkit.delays.paper_fit import PAPER_DELAY_MAX, PAPER_DELAY_MIN, paper_shape
from teleopkit.delays.units import UNITS, column_unit

__all__ = [
    "ConstantDelay",
    "DelayProfile",
    "FourierDelay",
    "SinusoidalDelay",
    "SwitchingDelay",
    "TraceDelay",
    "check_delays",
    "declared_bound",
    "delay_floor",
]

class DelayProfile(Protocol):
    """What the simulator needs from a delay profile.

    A profile that is one shape of time times a scale per scenario may also have a method
    ``factors(t)`` returning ``(shape (S,), scale (B,))`` whose outer product is ``sample(t)``
    bit for bit (:meth:`FourierDelay.factors`); the simulator then keeps one column of delays
    for the whole batch. A profile that jumps has ``jumps = True`` and a method
    ``sample_left(t)``, its left limits (:mod:`teleopkit.delays.jumps`).
    """

    @property
    def bound(self) -> float:
        """Declared upper bound in seconds."""
        ...

    @property
    def floor(self) -> float:
        """Declared lower bound in seconds (a certificate for interval delays needs it)."""
        ...

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delay in seconds at each time for each of the profile's ``B`` scenarios (``B = 1``
            when the profile is the same for every scenario), within ``[0, bound]``.
        """
        ...


def _per_scenario(name: str, value: float | np.ndarray) -> np.ndarray:
    """Return ``value`` as a finite 1-D array (one entry per scenario)."""
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"{name} must be a number or a 1-D array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array}")
    return array


def check_delays(kind: str, values: np.ndarray, bound: float) -> np.ndarray:
    """Return ``values`` if every one is finite and in ``[0, bound]``, else raise ValueError.

    The one check every delay profile applies to what it produces.

    Parameters
    ----------
    kind : str
        Name of the profile, for the message.
    values : ndarray
        Delays in seconds.
    bound : float
        The profile's declared upper bound in seconds.

    Returns
    -------
    ndarray
        ``values`` unchanged.

    Raises
    ------
    ValueError
        One line naming the profile and the offending value.
    """
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{kind} produced a non-finite delay")
    low, high = float(values.min(initial=0.0)), float(values.max(initial=0.0))
    if low < 0.0:
        raise ValueError(f"{kind} produced a negative delay ({low:.6g} s)")
    if high > bound:
        raise ValueError(f"{kind} reaches {high:.6g} s, above its declared bound {bound:.6g} s")
    return values


def delay_floor(profile: DelayProfile) -> float:
    """A profile's declared lower bound in seconds; 0 for a profile that declares none.

    Parameters
    ----------
    profile : DelayProfile
        Any delay profile.

    Returns
    -------
    float
        ``profile.floor`` when the profile has one, else 0 (the delay may reach 0).
    """
    return float(getattr(profile, "floor", 0.0))


def declared_bound(values: np.ndarray, bound: float) -> float:
    """A profile's bound: ``bound`` as given, or the largest value when ``bound`` is NaN.

    Parameters
    ----------
    values : ndarray
        The profile's delays in seconds.
    bound : float
        The declared bound, or NaN for none.

    Returns
    -------
    float
        The bound in seconds.
    """
    return float(np.max(values)) if math.isnan(bound) else float(bound)


def _trace_column(path: object, columns: Sequence[str], names: tuple[str, ...],
                  unit: str | None) -> tuple[str, float]:
    """The one column of a trace whose base name is in ``names``, and its unit in seconds."""
    found = [(column, factor) for column in columns
             for base, factor in [column_unit(str(column))] if base in names]
    if len(found) != 1:
        what = "no" if not found else "more than one"
        raise ValueError(f"delay trace {path} has {what} {names[0]} column ({' or '.join(names)}"
                         f", optionally with _s, _ms or _us); its columns: "
                         f"{', '.join(map(str, columns))}")
    column, factor = found[0]
    plain = column_unit(str(column))[0] == str(column).strip().lower()
    return column, (UNITS[unit] if unit is not None and plain else factor)


def _times(t: np.ndarray) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=float))


def _outer_product_of_factors(self: Any, t: np.ndarray) -> np.ndarray:
    """Return the delays at the times ``t``: the outer product of :meth:`factors`.

    Parameters
    ----------
    t : ndarray, shape (S,)
        Times in seconds (a scalar is one time).

    Returns
    -------
    ndarray, shape (S, B)
        Delay in seconds at each time, one column per scenario of the profile.

    Raises
    ------
    ValueError
        If a delay is negative, non-finite or above ``bound``.
    """
    return np.multiply.outer(*self.factors(t))


@dataclass(frozen=True)
class FourierDelay:
    """The paper's delay ``T(t) = scale * y(t) / y_max``, ``y`` the Fourier series of Fig. 3.

    ``y`` is the 16-harmonic fit of the paper's Fig. 3 (range about 0.903-1.000 s); the fit
    overshoots the paper's bound ``T* = 1 s`` by 0.03 % (its maximum is at most
    :data:`~teleopkit.delays.paper_fit.PAPER_DELAY_MAX`, 1.00031 s), so it is divided by that
    rigorous maximum: with ``scale <= 1`` the profile never exceeds 1 s, the bound certificates
    are computed for.

    Parameters
    ----------
    scale : float or ndarray, shape (B,)
        Per-scenario scale in seconds (the paper draws ``g_m, g_s ~ U[0.5, 1]`` per episode).
    bound : float, optional
        Declared bound, at least ``max(scale)`` (a lower one is refused); defaults to it.
    """

    scale: float | np.ndarray = 1.0
    bound: float = math.nan

    def __post_init__(self) -> None:
        scale = _per_scenario("delay scale", self.scale)
        if np.any(scale < 0):
            raise ValueError(f"delay scale must be non-negative, got {scale}")
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "bound", declared_bound(scale, self.bound))
        check_delays(type(self).__name__, scale, self.bound)  # the fit reaches up to the scale

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest scale times the fit's rigorous relative minimum."""
        return float(np.min(self.scale)) * PAPER_DELAY_MIN / PAPER_DELAY_MAX

    sample = _outer_product_of_factors

    def factors(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The delays at the times ``t`` as one shape of time and a scale per scenario.

        ``np.multiply.outer(shape, scale)`` is :meth:`sample` bit for bit; a simulator of many
        scenarios multiplies the factors as it reads them instead of storing ``S B`` delays.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds (a scalar is one time).

        Returns
        -------
        shape : ndarray, shape (S,)
            ``y(t) / y_max``.
        scale : ndarray, shape (B,)
            The scales in seconds.

        Raises
        ------
        ValueError
            If a delay is negative, non-finite or above ``bound``.
        """
        shape = paper_shape(_times(t)) / PAPER_DELAY_MAX
        scale = np.asarray(self.scale)
        # The shape is positive and the scales non-negative, so the extremes of the products are
        # those of the extreme shape values: checking two rows checks every value.
        extremes = np.multiply.outer([shape.min(), shape.max()], scale)
        check_delays(type(self).__name__, extremes, self.bound)
        return shape, scale.copy()


@dataclass(frozen=True)
class ConstantDelay:
    """A constant delay (per scenario).

    Parameters
    ----------
    value : float or ndarray, shape (B,)
        Delay in seconds.
    bound : float, optional
        Declared bound, at least ``max(value)`` (a lower one is refused); defaults to it.
    """

    value: float | np.ndarray = 0.5
    bound: float = math.nan

    def __post_init__(self) -> None:
        value = _per_scenario("constant delay", self.value)
        if np.any(value < 0):
            raise ValueError(f"constant delay must be non-negative, got {value}")
        object.__setattr__(self, "value", value)
        object.__setattr__(self, "bound", declared_bound(value, self.bound))
        check_delays(type(self).__name__, value, self.bound)

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest value."""
        return float(np.min(self.value))

    sample = _outer_product_of_factors

    def factors(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The delays at the times ``t`` as ones times the values (see :meth:`sample`).

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds (a scalar is one time).

        Returns
        -------
        shape : ndarray, shape (S,)
            Ones.
        scale : ndarray, shape (B,)
            The delays in seconds.

        Raises
        ------
        ValueError
            If a delay is negative, non-finite or above ``bound``.
        """
        value = check_delays(type(self).__name__, np.array(self.value), self.bound)
        return np.ones(_times(t).size), value


@dataclass(frozen=True)
class SinusoidalDelay:
    """``T(t) = mean + amplitude sin(2 pi frequency t + phase)``.

    Parameters
    ----------
    mean, amplitude : float
        Mean and amplitude in seconds (``amplitude <= mean``).
    frequency : float
        Frequency in Hz.
    phase : float or ndarray, shape (B,)
        Phase in radians, per scenario.
    """

    mean: float = 0.5
    amplitude: float = 0.4
    frequency: float = 0.5
    phase: float | np.ndarray = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.amplitude <= self.mean or not math.isfinite(self.mean):
            raise ValueError(f"sinusoidal delay needs 0 <= amplitude <= mean, got mean "
                             f"{self.mean}, amplitude {self.amplitude}")
        if not math.isfinite(self.frequency) or self.frequency < 0:
            raise ValueError(f"sinusoidal delay frequency must be >= 0, got {self.frequency}")
        object.__setattr__(self, "phase", _per_scenario("delay phase", self.phase))

    @property
    def bound(self) -> float:
        """Declared upper bound ``mean + amplitude``."""
        return self.mean + self.amplitude

    @property
    def floor(self) -> float:
        """Declared lower bound ``mean - amplitude``."""
        return self.mean - self.amplitude

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds (a scalar is one time).

        Returns
        -------
        ndarray, shape (S, B)
            Delay in seconds at each time, one column per entry of ``phase``.

        Raises
        ------
        ValueError
            If a delay is negative, non-finite or above ``bound``.
        """
        angle = 2.0 * np.pi * self.frequency * _times(t)[:, None] + np.asarray(self.phase)
        values = self.mean + self.amplitude * np.sin(angle)
        return check_delays(type(self).__name__, values, self.bound)


def _uniform_hash(seed: int, index: np.ndarray, stream: np.ndarray) -> np.ndarray:
    """Counter-based uniforms in [0, 1): the SplitMix64 finaliser of ``(seed, index, stream)``."""
    with np.errstate(over="ignore"):
        z = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
             + index.astype(np.uint64) * np.uint64(0xBF58476D1CE4E5B9)
             + stream.astype(np.uint64) * np.uint64(0x94D049BB133111EB))
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(float) / float(2**53)


@dataclass(frozen=True)
class SwitchingDelay:
    """Bounded random delay, piecewise constant over intervals of length ``dwell``.

    Each interval holds a value drawn uniformly from ``[low, high]`` (``mode="uniform"``) or one of
    the two extremes (``mode="extremes"``, the adversarial bang-bang case; with ``dwell`` equal to
    the control period it switches as fast as the loop runs). Values come from a counter-based hash
    of ``(seed, interval, scenario)``, so any time can be sampled in any order, reproducibly.

    Parameters
    ----------
    low, high : float
        Range of the delay in seconds.
    dwell : float
        Length of each constant interval in seconds.
    mode : {"uniform", "extremes"}
        Distribution of the values.
    seed : int
        Seed of the sequence.
    batch : int
        Number of independent scenarios.
    """

    low: float = 0.0
    high: float = 1.0
    dwell: float = 0.01
    mode: Literal["uniform", "extremes"] = "uniform"
    seed: int = 0
    batch: int = 1
    jumps = True
    """It is constant between switches (:mod:`teleopkit.delays.jumps`)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.high) and 0 <= self.low <= self.high):
            raise ValueError(f"switching delay needs 0 <= low <= high, got {self.low}, {self.high}")
        if not math.isfinite(self.dwell) or self.dwell <= 0:
            raise ValueError(f"switching delay dwell must be positive, got {self.dwell}")
        if self.mode not in ("uniform", "extremes"):
            raise ValueError(f"switching delay mode must be 'uniform' or 'extremes', got "
                             f"{self.mode!r}")
        if self.batch < 1:
            raise ValueError(f"switching delay batch must be >= 1, got {self.batch}")

    @property
    def bound(self) -> float:
        """Declared upper bound ``high``."""
        return self.high

    @property
    def floor(self) -> float:
        """Declared lower bound ``low``."""
        return self.low

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds (a scalar is one time).

        Returns
        -------
        ndarray, shape (S, B)
            Delay in seconds at each time, one column per scenario (``B = batch``).

        Raises
        ------
        ValueError
            If a delay is negative, non-finite or above ``bound``.
        """
        return self._on(np.floor(_times(t) / self.dwell + 1e-9))

    def sample_left(self, t: np.ndarray) -> np.ndarray:
        """Return the delays just before the times ``t`` (at a switch: the old value).

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.

        Returns
        -------
        ndarray, shape (S, B)
            Delay in seconds at each time, one column per scenario.
        """
        return self._on(np.ceil(_times(t) / self.dwell - 1e-9) - 1)

    def _on(self, interval: np.ndarray) -> np.ndarray:
        """The delays held on the intervals ``interval`` (indices, as floats)."""
        u = _uniform_hash(self.seed, interval.astype(np.int64)[:, None],
                          np.arange(self.batch)[None, :])
        if self.mode == "extremes":
            u = np.round(u)
        return check_delays(type(self).__name__, self.low + (self.high - self.low) * u, self.bound)


@dataclass(frozen=True)
class TraceDelay:
    """A recorded delay trace, linearly interpolated and held constant after its last sample.

    Runs start at ``t = 0``, so the trace must start there or earlier: a later start (recorded
    timestamps, for example) is refused rather than extrapolated. :func:`teleopkit.simulate`
    and campaigns also refuse a trace that ends before their run does.

    Parameters
    ----------
    times : ndarray, shape (N,)
        Strictly increasing sample times in seconds, the first at or before 0.
    delays : ndarray, shape (N,)
        Delay at each sample time in seconds.
    bound : float, optional
        Declared bound, at least the trace's maximum (a lower one is refused); defaults to it.
    """

    times: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))
    delays: np.ndarray = field(default_factory=lambda: np.array([0.5, 0.5]))
    bound: float = math.nan

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        delays = np.asarray(self.delays, dtype=float)
        if times.ndim != 1 or times.shape != delays.shape or times.size < 2:
            raise ValueError("delay trace needs two equal-length columns with at least 2 rows")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(delays))):
            raise ValueError("delay trace contains non-finite values")
        if np.any(np.diff(times) <= 0):
            raise ValueError("delay trace times must be strictly increasing")
        if times[0] > 0:
            raise ValueError(f"delay trace starts at {times[0]:g} s, after t = 0 where runs "
                             "start: subtract its first time from its times")
        if np.any(delays < 0):
            raise ValueError(f"delay trace has a negative delay ({delays.min():.6g} s)")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "delays", delays)
        object.__setattr__(self, "bound", declared_bound(delays, self.bound))
        check_delays(type(self).__name__, delays, self.bound)  # what interpolation reaches

    @property
    def floor(self) -> float:
        """Declared lower bound: the smallest sample (interpolation never goes below it)."""
        return float(self.delays.min())

    @classmethod
    def from_csv(cls, path: str | Path, unit: str | None = None,
                 bound: float = math.nan) -> TraceDelay:
        """Read a trace from a CSV file with a time and a delay column, by column name.

        The time column is ``t`` or ``time``, the delay column ``delay`` or ``latency``, each
        with an optional unit suffix (``_s``, ``_ms``, ``_us``; seconds without one), for
        example ``t,delay_ms``. Other headers are refused, naming the columns found.

        Parameters
        ----------
        path : str or Path
            CSV file.
        unit : {"s", "ms", "us"}, optional
            Unit of both columns when their names carry none (seconds by default).
        bound : float, optional
            Declared bound in seconds; defaults to the trace's maximum.

        Returns
        -------
        TraceDelay
            The trace, in seconds.

        Raises
        ------
        ValueError
            One line: unreadable file, missing or ambiguous columns, non-numeric values, a
            delay above ``bound``.
        """
        import pandas as pd

        if unit is not None and unit not in UNITS:
            raise ValueError(f"delay trace unit must be one of {', '.join(UNITS)}, got {unit!r}")
        try:
            table = pd.read_csv(path)
        except (OSError, ValueError, pd.errors.ParserError) as error:
            reason = getattr(error, "strerror", None) or str(error).splitlines()[0]
            raise ValueError(f"cannot read delay trace {path}: {reason}") from None
        columns = [_trace_column(path, list(table.columns), names, unit)
                   for names in (("t", "time"), ("delay", "latency"))]
        try:
            times, delays = (table[c].to_numpy(dtype=float) * scale for c, scale in columns)
        except ValueError:
            raise ValueError(f"delay trace {path} has non-numeric values") from None
        return cls(times, delays, bound)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Return the delays at the times ``t``.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds (a scalar is one time).

        Returns
        -------
        ndarray, shape (S, 1)
            Delay in seconds at each time, one column shared by every scenario.

        Raises
        ------
        ValueError
            If a delay is negative, non-finite or above ``bound``.
        """
        values = np.interp(_times(t), self.times, self.delays)[:, None]
        return check_delays(type(self).__name__, values, self.bound)
