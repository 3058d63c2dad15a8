"""Delay profiles from short text specs (the command line's ``--delay``, campaign factors)."""

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

__all__ = ["parse_delay"]


def parse_delay(spec: str, rng: np.random.Generator | None = None,
                ) -> tuple[DelayProfile, DelayProfile]:
    """Build the forward (``T_l``) and backward (``T_r``) profiles from a command-line spec.

    Parameters
    ----------
    spec : str
        ``paper`` (the Fourier profile with scales drawn from ``U[0.5, 1]``), ``constant:T``,
        ``sine:MEAN:AMPLITUDE:FREQUENCY``, ``switching:LOW:HIGH:DWELL`` (adversarial extremes) or
        ``csv:PATH`` (the same trace on both channels).
    rng : numpy.random.Generator, optional
        Source of the paper profile's scales and the switching seed.

    Returns
    -------
    tuple of DelayProfile
        Forward and backward profiles.
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    kind, _, rest = spec.partition(":")
    try:
        if kind == "paper" and not rest:
            scales = rng.uniform(0.5, 1.0, size=2)
            return FourierDelay(scales[0]), FourierDelay(scales[1])
        if kind == "csv" and rest:
            trace = TraceDelay.from_csv(rest)
            return trace, trace
        numbers = [float(x) for x in rest.split(":")] if rest else []
        if kind == "constant" and len(numbers) == 1:
            return ConstantDelay(numbers[0]), ConstantDelay(numbers[0])
        if kind == "sine" and len(numbers) == 3:
            mean, amplitude, frequency = numbers
            return (SinusoidalDelay(mean, amplitude, frequency),
                    SinusoidalDelay(mean, amplitude, frequency, phase=np.pi / 2))
        if kind == "switching" and len(numbers) == 3:
            low, high, dwell = numbers
            seed = int(rng.integers(2**31))
            return (SwitchingDelay(low, high, dwell, "extremes", seed),
                    SwitchingDelay(low, high, dwell, "extremes", seed + 1))
    except ValueError as error:
        if "could not convert" not in str(error):
            raise
    raise ValueError(f"unknown delay spec {spec!r}; use paper, constant:T, sine:MEAN:AMP:FREQ, "
                     f"switching:LOW:HIGH:DWELL or csv:PATH")
