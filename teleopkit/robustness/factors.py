"""The factors of a robustness campaign: what may vary, its type, default and checks.

Factors (:data:`FACTORS`; every column is always present, unset factors hold their default, or
for a setup other than the paper's its own value: see :mod:`teleopkit.robustness.spec`):

========================  ========  =============================================================
factor                    default   meaning
========================  ========  =============================================================
``joint_stiffness``       100       remote joint stiffness ``S_r`` on every joint (N m/rad)
``rotor_inertia``         0.3       remote rotor inertia ``J_r`` on every joint (kg m^2)
``remote_mass_scale``     1         factor on the remote arm's link masses
``local_mass_scale``      1         factor on the local arm's link masses
``kl``, ``bl``            25, 10    local P+d gains ``K_l``, ``B_l`` on every joint
``delay``                 paper     a spec of :func:`teleopkit.delays.parse_delay` (``paper``,
                                    ``constant:T``, ``sine:M:A:F``, ``switching:LO:HI:DWELL``,
                                    ``csv:PATH`` relative to the spec file), or ``setup``: the
                                    setup's network (the default for a setup other than the
                                    paper's)
``delay_scale``           1         factor on both delays and their bounds
``reference_gain``        random    operator reference gains ``G``: ``random`` (the paper's draw),
                                    one number for every joint, or ``G1,G2``
``kr``, ``br``            10, 30    fixed remote gains ``K_r``, ``B_r`` on every joint
``seed``                  0         seed of the scenario's random draws
``controller``            fixed     ``fixed`` (the gains ``kr``, ``br``) or ``policy:PATH``: a
                                    trained policy (:class:`~teleopkit.rl.policy.GainPolicy` file,
                                    relative to the spec file) retunes the gains every control
                                    period through the safety layer of the closed-form
                                    certificate of the row's teleoperator
                                    (:func:`~teleopkit.certification.default_certificate`);
                                    ``kr``, ``br`` are then unused
========================  ========  =============================================================

A policy changes the gains every control period, which the closed-form certificate (constant
gains) does not cover; its projection keeps every applied gain inside the certified set.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["DISTRIBUTIONS", "FACTORS", "MODEL_FACTORS", "Factor", "FactorInfo", "factor_dtypes"]

DISTRIBUTIONS = ("levels", "uniform", "loguniform")
"""How a factor is given: a list of levels, or a continuous draw (random campaigns only)."""


def _finite(value: float) -> bool:
    return math.isfinite(value)


@dataclass(frozen=True)
class FactorInfo:
    """What a factor is: its type, default, admissible values and whether it changes the model.

    Parameters
    ----------
    kind : {"float", "int", "str"}
        Type of the values.
    default : float or int or str
        Value when the spec does not set the factor.
    check : callable
        Predicate on one (converted) value.
    requirement : str
        The predicate in words, for error messages.
    model : bool
        Whether the factor changes the teleoperator (scenarios of a chunk are batched per
        distinct teleoperator).
    """

    kind: str
    default: float | int | str
    check: Callable[[Any], bool]
    requirement: str
    model: bool = False


def _positive(value: float) -> bool:
    return _finite(value) and value > 0


def _non_negative(value: float) -> bool:
    return _finite(value) and value >= 0


FACTORS: dict[str, FactorInfo] = {
    "joint_stiffness": FactorInfo("float", 100.0, _positive, "finite and > 0", model=True),
    "rotor_inertia": FactorInfo("float", 0.3, _positive, "finite and > 0", model=True),
    "remote_mass_scale": FactorInfo("float", 1.0, _positive, "finite and > 0", model=True),
    "local_mass_scale": FactorInfo("float", 1.0, _positive, "finite and > 0", model=True),
    "kl": FactorInfo("float", 25.0, _non_negative, "finite and >= 0", model=True),
    "bl": FactorInfo("float", 10.0, _non_negative, "finite and >= 0", model=True),
    "delay": FactorInfo("str", "paper", lambda v: bool(v), "a delay spec"),
    "delay_scale": FactorInfo("float", 1.0, _non_negative, "finite and >= 0"),
    "reference_gain": FactorInfo("str", "random", lambda v: bool(v),
                                 "'random', a number or G1,G2"),
    "kr": FactorInfo("float", 10.0, _non_negative, "finite and >= 0"),
    "br": FactorInfo("float", 30.0, _non_negative, "finite and >= 0"),
    "seed": FactorInfo("int", 0, lambda v: 0 <= v < 2**63, "an integer >= 0"),
    "controller": FactorInfo("str", "fixed", lambda v: bool(v), "'fixed' or policy:PATH"),
}
"""The factors a campaign may vary, in the order of the table's columns."""

MODEL_FACTORS = tuple(name for name, info in FACTORS.items() if info.model)
"""Factors that change the teleoperator."""


def _convert(name: str, value: Any) -> float | int | str:
    """One factor value as the factor's type, or a one-line ValueError."""
    info = FACTORS[name]
    if info.kind == "str":
        if name == "reference_gain" and isinstance(value, int | float) and not isinstance(
                value, bool):
            value = repr(float(value))
        if not isinstance(value, str):
            raise ValueError(f"factor {name!r}: values must be strings, got {value!r}")
        converted: float | int | str = value.strip()
    elif info.kind == "int":
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ValueError(f"factor {name!r}: values must be {info.requirement}, got {value!r}")
        converted = int(value)
    else:
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise ValueError(f"factor {name!r}: values must be numbers, got {value!r}")
        converted = float(value)
    if not info.check(converted):
        raise ValueError(f"factor {name!r}: values must be {info.requirement}, got {value!r}")
    return converted


@dataclass(frozen=True)
class Factor:
    """How one factor varies: levels, or a continuous draw between ``low`` and ``high``.

    Parameters
    ----------
    name : str
        A key of :data:`FACTORS`.
    levels : tuple
        Values for ``distribution="levels"`` (one level: a fixed value).
    distribution : {"levels", "uniform", "loguniform"}
        ``levels`` (grid or uniform choice), or a continuous draw (random campaigns only).
    low, high : float
        Range of a continuous draw.
    """

    name: str
    levels: tuple[float | int | str, ...] = ()
    distribution: str = "levels"
    low: float = math.nan
    high: float = math.nan

    def __post_init__(self) -> None:
        if self.name not in FACTORS:
            raise ValueError(f"unknown factor {self.name!r}; known: {', '.join(FACTORS)}")
        if self.distribution not in DISTRIBUTIONS:
            raise ValueError(f"factor {self.name!r}: unknown distribution "
                             f"{self.distribution!r}; use a list, linspace, range, uniform or "
                             "loguniform")
        if self.distribution == "levels":
            self._check_levels()
        else:
            self._check_range()

    def _check_levels(self) -> None:
        levels = tuple(_convert(self.name, v) for v in self.levels)
        if not levels:
            raise ValueError(f"factor {self.name!r} has no values")
        if len(set(levels)) != len(levels):
            raise ValueError(f"factor {self.name!r} repeats a value")
        object.__setattr__(self, "levels", levels)

    def _check_range(self) -> None:
        if FACTORS[self.name].kind != "float":
            raise ValueError(f"factor {self.name!r}: {self.distribution} draws need a numeric "
                             "factor; give a list of values")
        low, high = (float(_convert(self.name, v)) for v in (self.low, self.high))
        if low >= high:
            raise ValueError(f"factor {self.name!r}: {self.distribution} needs LOW < HIGH, got "
                             f"[{low:g}, {high:g}]")
        if self.distribution == "loguniform" and low <= 0:
            raise ValueError(f"factor {self.name!r}: loguniform needs LOW > 0, got {low:g}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    @classmethod
    def parse(cls, name: str, value: Any) -> Factor:
        """Read a factor from plain data (a value, a list, or a one-key mapping).

        Parameters
        ----------
        name : str
            Factor name.
        value : Any
            ``V``, ``[V1, V2, ...]``, ``{linspace: [LO, HI, N]}``, ``{range: [START, STOP]}``,
            ``{uniform: [LO, HI]}`` or ``{loguniform: [LO, HI]}``.

        Returns
        -------
        Factor
            The checked factor.
        """
        if name not in FACTORS:
            raise ValueError(f"unknown factor {name!r}; known: {', '.join(FACTORS)}")
        if isinstance(value, Mapping):
            return cls._parse_mapping(name, value)
        if isinstance(value, list | tuple):
            return cls(name, tuple(value))
        return cls(name, (value,))

    @classmethod
    def _parse_mapping(cls, name: str, value: Mapping[str, Any]) -> Factor:
        if len(value) != 1:
            raise ValueError(f"factor {name!r}: give one of linspace, range, uniform, loguniform; "
                             f"got {sorted(map(str, value))}")
        (key, args), = value.items()
        sizes = {"linspace": 3, "range": 2, "uniform": 2, "loguniform": 2}
        if key not in sizes:
            raise ValueError(f"factor {name!r}: unknown distribution {key!r}; use a list, "
                             "linspace, range, uniform or loguniform")
        if not isinstance(args, list | tuple) or len(args) != sizes[key]:
            raise ValueError(f"factor {name!r}: {key} needs a list of {sizes[key]} numbers")
        if key == "linspace":
            low, high = _numbers(name, args[:2])
            return cls(name, tuple(np.linspace(low, high, _count(name, args[2]))))
        if key == "range":
            start, stop = (_count(name, a, minimum=0) for a in args)
            return cls(name, tuple(range(start, stop)))
        low, high = _numbers(name, args)
        return cls(name, (), key, low, high)

    @property
    def size(self) -> int:
        """Number of levels (0 for a continuous draw)."""
        return len(self.levels)

    def draw(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """Draw ``size`` values (levels uniformly, or the continuous distribution).

        Parameters
        ----------
        rng : numpy.random.Generator
            Random source.
        size : int
            Number of values.

        Returns
        -------
        ndarray, shape (size,)
            The values.
        """
        if self.distribution == "uniform":
            return rng.uniform(self.low, self.high, size)
        if self.distribution == "loguniform":
            return np.exp(rng.uniform(math.log(self.low), math.log(self.high), size))
        return np.asarray(self.levels, dtype=object)[rng.integers(len(self.levels), size=size)]

    def to_data(self) -> Any:
        """Plain-data form (inverse of :meth:`parse`)."""
        if self.distribution == "levels":
            return list(self.levels)
        return {self.distribution: [self.low, self.high]}


def _numbers(name: str, values: Iterable[Any]) -> tuple[float, ...]:
    out = []
    for value in values:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"factor {name!r}: expected numbers, got {value!r}")
        out.append(float(value))
    return tuple(out)


def _count(name: str, value: Any, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"factor {name!r}: expected an integer >= {minimum}, got {value!r}")
    return value


_DTYPES = {"float": "float64", "int": "int64", "str": "str"}


def factor_dtypes() -> dict[str, str]:
    """The pandas dtype of every factor column (what a campaign table holds).

    Returns
    -------
    dict of str to str
        Factor name to ``float64``, ``int64`` or ``str``.
    """
    return {name: _DTYPES[info.kind] for name, info in FACTORS.items()}
