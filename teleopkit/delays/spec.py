"""Delay profiles from short text specs (the command line's ``--delay``, campaign factors).

Times are in seconds unless they say otherwise (``500ms``): a bare ``500`` is 500 seconds, and
:func:`check_duration` refuses delays that long for a run of 40 s, suggesting the unit.
"""

from __future__ import annotations

import numpy as np

from teleopkit.delays.profiles import (
    ConstantDelay,
    DelayProfile,
    FourierDelay,
    SinusoidalDelay,
    SwitchingDelay,
    TraceDelay,
)
from teleopkit.delays.units import seconds

__all__ = ["check_delay_bound", "check_duration", "check_trace_ends", "delay_pair",
           "parse_delay"]


_SPECS = "paper, constant:T, sine:MEAN:AMP:FREQ, switching:LOW:HIGH:DWELL or csv:PATH"
_TIMES = {"constant": ("delay",), "sine": ("mean", "amplitude", "frequency"),
          "switching": ("low", "high", "dwell")}


def parse_delay(spec: str, rng: np.random.Generator | None = None,
                ) -> tuple[DelayProfile, DelayProfile]:
    """Build the forward (``T_l``) and backward (``T_r``) profiles from a command-line spec.

    Times are seconds unless they carry a unit: ``constant:500ms`` is ``constant:0.5``.

    Parameters
    ----------
    spec : str
        ``paper`` (the Fourier profile with scales drawn from ``U[0.5, 1]``), ``constant:T``,
        ``sine:MEAN:AMPLITUDE:FREQUENCY`` (frequency in Hz), ``switching:LOW:HIGH:DWELL``
        (adversarial extremes) or ``csv:PATH`` (the same trace on both channels, columns named
        with their units: :meth:`~teleopkit.delays.profiles.TraceDelay.from_csv`).
    rng : numpy.random.Generator, optional
        Source of the paper profile's scales and the switching seed.

    Returns
    -------
    tuple of DelayProfile
        Forward and backward profiles.

    Raises
    ------
    ValueError
        One line naming the spec and what is wrong with it.
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    kind, _, rest = str(spec).strip().partition(":")
    if kind == "paper" and not rest:
        scales = rng.uniform(0.5, 1.0, size=2)  # the paper's g_m, g_s
        return FourierDelay(scales[0]), FourierDelay(scales[1])
    if kind == "csv" and rest:
        trace = TraceDelay.from_csv(rest)
        return trace, trace
    names = _TIMES.get(kind)
    parts = rest.split(":") if rest else []
    if names is None or len(parts) != len(names):
        raise ValueError(f"unknown delay spec {spec!r}; use {_SPECS}")
    values = [_number(part, name) if name == "frequency" else seconds(part, f"{kind} {name}")
              for part, name in zip(parts, names, strict=True)]
    if kind == "constant":
        return ConstantDelay(values[0]), ConstantDelay(values[0])
    if kind == "sine":
        mean, amplitude, frequency = values
        return (SinusoidalDelay(mean, amplitude, frequency),
                SinusoidalDelay(mean, amplitude, frequency, phase=np.pi / 2))
    low, high, dwell = values
    seed = int(rng.integers(2**31))
    return (SwitchingDelay(low, high, dwell, "extremes", seed),
            SwitchingDelay(low, high, dwell, "extremes", seed + 1))


def _number(text: str, name: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"sine {name} must be a number (Hz), got {text!r}") from None


def check_duration(profiles: tuple[DelayProfile, DelayProfile], duration: float) -> None:
    """Refuse delays that reach the run's length, and traces that end before it.

    A delay as long as the run is almost always a number meant in milliseconds; a recorded
    trace that ends early would hold its last delay (:func:`check_trace_ends`).

    Parameters
    ----------
    profiles : tuple of DelayProfile
        Forward and backward delays.
    duration : float
        Length of the run in seconds.

    Raises
    ------
    ValueError
        One line with the delay (or the trace's end), the duration and what to change.
    """
    check_trace_ends(profiles, duration)
    check_delay_bound(max(profile.bound for profile in profiles), duration)


def check_delay_bound(bound: float, duration: float, units_hint: bool = True) -> None:
    """Refuse a delay bound that reaches the run's length (a number meant in milliseconds).

    Parameters
    ----------
    bound : float
        The largest delay of the run in seconds (both directions).
    duration : float
        Length of the run in seconds.
    units_hint : bool
        Whether the message may suggest milliseconds (not for delays a factor scaled).

    Raises
    ------
    ValueError
        One line with the delay, the duration and, for a bound above 1 s, the unit to write.
    """
    if bound >= duration:
        hint = (f"; delays are in seconds: {bound:g} milliseconds is written {bound:g}ms (a "
                "trace column delay_ms)" if bound > 1 and units_hint else "")
        raise ValueError(f"the delay reaches {bound:g} s, not shorter than the {duration:g} s "
                         f"run{hint}")


def check_trace_ends(profiles: tuple[DelayProfile, DelayProfile], duration: float) -> None:
    """Refuse a recorded trace that ends before the run does: it would hold its last delay.

    Parameters
    ----------
    profiles : tuple of DelayProfile
        Forward and backward delays (only :class:`~teleopkit.delays.profiles.TraceDelay`
        profiles are checked).
    duration : float
        Length of the run in seconds.

    Raises
    ------
    ValueError
        One line with the trace's end and the run's length.
    """
    ends = [float(p.times[-1]) for p in profiles if isinstance(p, TraceDelay)]
    if ends and min(ends) < duration:
        raise ValueError(f"the delay trace ends at {min(ends):g} s, before the {duration:g} s "
                         "run does: record a longer trace or shorten the run")


def delay_pair(delay: object, rng: np.random.Generator) -> tuple[DelayProfile, DelayProfile]:
    """The forward and backward profiles a ``delay`` argument names.

    Parameters
    ----------
    delay : str, float or (DelayProfile, DelayProfile)
        A spec for :func:`parse_delay`, a constant delay in seconds, or the two profiles.
    rng : numpy.random.Generator
        Source of a spec's random parameters.

    Returns
    -------
    tuple of DelayProfile
        Forward and backward profiles.

    Raises
    ------
    ValueError
        One line saying what ``delay`` should be.
    """
    if isinstance(delay, str):
        return parse_delay(delay, rng)
    if isinstance(delay, int | float) and not isinstance(delay, bool):
        return ConstantDelay(float(delay)), ConstantDelay(float(delay))
    if isinstance(delay, tuple | list):
        if len(delay) == 2 and all(callable(getattr(p, "sample", None)) for p in delay):
            return delay[0], delay[1]
        got = f"{len(delay)} item(s), not two delay profiles"
    else:
        got = repr(delay)
    raise ValueError("delay must be a spec string, a constant in seconds or a pair of delay "
                     f"profiles (forward, backward), got {got}")
