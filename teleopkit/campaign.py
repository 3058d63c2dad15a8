"""Robustness campaigns: thousands of scenarios, one tidy table, on Dask.

A campaign is a :class:`CampaignSpec`: *factors* (delay profile, delay scale, operator reference
gain, remote gains, perturbed teleoperator parameters, seed) crossed as a full grid or sampled at
random, the episode settings and a divergence threshold. :func:`run_campaign` expands it into one
row per scenario (:meth:`CampaignSpec.expand`), cuts the rows into chunks, simulates each chunk on
a Dask cluster as batches of the :class:`~teleopkit.simulator.Simulator` (one batch per distinct
teleoperator in the chunk, not one process per scenario), writes every finished chunk as its own
Parquet file and returns the assembled table: the factor columns plus RMS / IAE / maximum of the
tracking and damping errors, the peak position, a growth ratio, a ``diverged`` flag and the wall
time. A campaign that was interrupted resumes: only the chunks whose files are missing run again.

Factors (:data:`FACTORS`; every column is always present, unset factors hold their default):

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
                                    ``csv:PATH`` relative to the spec file)
``delay_scale``           1         factor on both delays and their bounds
``reference_gain``        random    operator reference gains ``G``: ``random`` (the paper's draw),
                                    one number for every joint, or ``G1,G2``
``kr``, ``br``            10, 30    fixed remote gains ``K_r``, ``B_r`` on every joint
``seed``                  0         seed of the scenario's random draws
``controller``            fixed     ``fixed`` (the gains ``kr``, ``br``) or ``policy:PATH``: a
                                    trained policy (:class:`~teleopkit.agent.GainPolicy` file,
                                    relative to the spec file) retunes the gains every control
                                    period through the safety layer of the closed-form
                                    certificate of the row's teleoperator
                                    (:func:`~teleopkit.env.default_certificate`); ``kr``, ``br``
                                    are then unused
========================  ========  =============================================================

A policy changes the gains every control period, which the closed-form certificate (constant
gains) does not cover; its projection keeps every applied gain inside the certified set.

Each factor is written in the spec as a single value (fixed), a list of levels, ``{linspace: [LO,
HI, N]}`` or ``{range: [START, STOP]}`` (levels), or, in ``mode: random`` only, ``{uniform: [LO,
HI]}`` or ``{loguniform: [LO, HI]}``. A grid crosses all levels (the parameter factors outermost,
``seed`` innermost); a random campaign draws ``samples`` scenarios, each factor from its own
generator seeded by the spec's ``seed`` and the factor's position in :data:`FACTORS` (levels are
drawn uniformly), and a ``seed`` per scenario unless the ``seed`` factor is given.

Reproducibility: a row is reproduced from its own columns. Its randomness comes from
``numpy.random.default_rng(seed)`` in the order of :func:`teleopkit.simulator.simulate` (reference
gains first, then the delay profile's draws), so with default parameters and ``delay_scale = 1`` a
row matches ``simulate((kr, br), duration, delay, seed)``. Rows do not depend on the chunk size,
the number of workers or the scheduler, except ``wall_time`` and ``chunk``.

Divergence (the criterion of :mod:`teleopkit.falsify`): ``diverged`` is true when the state
becomes non-finite, a position (local, remote link or motor angle) exceeds ``divergence_radius``,
or the motion grows: ``growth``, the peak position magnitude over the last quarter of the run over
that of the second quarter, exceeds 1 while the last-quarter peak exceeds :data:`GROWTH_FLOOR`
in a run of at least :data:`GROWTH_MIN_DURATION` (the operator's reference decays, so a stable run
shrinks; a shorter run is mostly its initial transient). The error metrics of a non-finite run
are ``inf``; ``max_position`` and ``growth`` let a user apply other criteria.

Example spec (YAML; JSON and TOML files hold the same keys)::

    mode: grid
    duration: 40
    factors:
      delay: [paper, "constant:0.5", "switching:0:1:0.05"]
      joint_stiffness: [50, 100, 200]
      kr: [5, 10, 20]
      br: 30
      seed: {range: [0, 8]}
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import time
import uuid
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from teleopkit.delay_ops import scale_delay, stack_delays
from teleopkit.delays import DelayProfile, TraceDelay, parse_delay
from teleopkit.env import default_certificate, observation
from teleopkit.params import ElasticJoints, PDGains, PlanarArm, TeleoperatorParams, paper_setup
from teleopkit.safety import SafetyLayer
from teleopkit.scenarios import Scenario, sample_reference_gains
from teleopkit.simulator import DEFAULT_DT, Simulator, StepResult

if TYPE_CHECKING:
    from distributed import Client

    from teleopkit.agent import GainPolicy

__all__ = [
    "FACTORS",
    "GROWTH_FLOOR",
    "GROWTH_MIN_DURATION",
    "MAX_SCENARIOS",
    "METRIC_COLUMNS",
    "MODEL_FACTORS",
    "CampaignInterrupted",
    "CampaignSpec",
    "ChunkTask",
    "Factor",
    "FactorInfo",
    "local_cluster",
    "plan_chunks",
    "run_campaign",
    "simulate_chunk",
]

MAX_SCENARIOS = 10_000_000
"""Largest campaign :meth:`CampaignSpec.expand` accepts."""

GROWTH_FLOOR = 0.01
"""Smallest last-quarter peak position (rad) at which a growth above 1 counts as divergence."""

GROWTH_MIN_DURATION = 10.0
"""Shortest run (s) whose growth counts as divergence (shorter runs are mostly transient)."""

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

METRIC_COLUMNS = ("rms_track", "iae_track", "max_track", "rms_damp", "iae_damp", "max_damp",
                  "max_position", "growth", "diverged", "wall_time")
"""Result columns after the factor columns, the reference gains ``G_i`` and ``delay_bound``."""

_SETTINGS = {"mode", "samples", "seed", "duration", "dt", "control_period", "divergence_radius",
             "factors"}


# --- factors --------------------------------------------------------------------------------------


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


# --- spec -----------------------------------------------------------------------------------------


def _setting(name: str, value: Any, kind: type, positive: bool = True) -> Any:
    """Check one top-level setting (a positive finite number or an integer)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"campaign {name} must be a number, got {value!r}")
    if kind is int and (not isinstance(value, int) or value < (1 if positive else 0)):
        raise ValueError(f"campaign {name} must be an integer >= {int(positive)}, got {value!r}")
    if kind is float and not (math.isfinite(value) and value > 0):
        raise ValueError(f"campaign {name} must be positive and finite, got {value!r}")
    return kind(value)


@dataclass(frozen=True)
class CampaignSpec:
    """A robustness campaign: factors, sampling and episode settings.

    Parameters
    ----------
    factors : tuple of Factor
        The varied (or fixed) factors; the others hold their :data:`FACTORS` default.
    mode : {"grid", "random"}
        Full factorial grid of the levels, or ``samples`` random scenarios.
    samples : int
        Number of scenarios of a random campaign (0 for a grid).
    seed : int
        Seed of a random campaign's draws.
    duration : float
        Episode length in seconds.
    dt : float
        Integration step in seconds.
    control_period : float
        Gain hold period in seconds (a multiple of ``dt``).
    divergence_radius : float
        Position magnitude (rad) that counts as divergence.
    base_dir : str
        Directory against which ``csv:PATH`` delay traces are resolved (the spec file's).

    Examples
    --------
    >>> spec = CampaignSpec.from_dict({"factors": {"kr": [5, 10], "seed": {"range": [0, 3]}}})
    >>> table = spec.expand()
    >>> len(table), table["kr"].unique().tolist()
    (6, [5.0, 10.0])
    """

    factors: tuple[Factor, ...] = ()
    mode: str = "grid"
    samples: int = 0
    seed: int = 0
    duration: float = 40.0
    dt: float = DEFAULT_DT
    control_period: float = 0.01
    divergence_radius: float = 20.0
    base_dir: str = ""

    def __post_init__(self) -> None:
        names = [f.name for f in self.factors]
        if len(set(names)) != len(names):
            raise ValueError("a factor is given twice")
        order = list(FACTORS)
        object.__setattr__(self, "factors",
                           tuple(sorted(self.factors, key=lambda f: order.index(f.name))))
        self._check_mode()
        for name in ("duration", "dt", "control_period", "divergence_radius"):
            _setting(name, getattr(self, name), float)
        _setting("seed", self.seed, int, positive=False)
        substeps = round(self.control_period / self.dt)
        if substeps < 1 or abs(substeps * self.dt - self.control_period) > 1e-9 * self.dt:
            raise ValueError(f"campaign control_period {self.control_period:g} must be a "
                             f"multiple of dt {self.dt:g}")
        for delay in self.factor("delay").levels or ():
            _check_delay(str(delay), self.base_dir)
        for gain in self.factor("reference_gain").levels or ():
            _reference_gains(str(gain), paper_setup().n_joints, None)
        for controller in self.factor("controller").levels or ():
            _check_controller(str(controller), self.base_dir)

    def _check_mode(self) -> None:
        if self.mode not in ("grid", "random"):
            raise ValueError(f"campaign mode must be 'grid' or 'random', got {self.mode!r}")
        if self.mode == "random":
            _setting("samples", self.samples, int)
            return
        if self.samples:
            raise ValueError("campaign samples is for mode: random (a grid crosses all levels)")
        for factor in self.factors:
            if factor.distribution != "levels":
                raise ValueError(f"factor {factor.name!r}: {factor.distribution} draws need "
                                 "mode: random; a grid takes a list, linspace or range")

    def factor(self, name: str) -> Factor:
        """The factor ``name`` as given, or its default as a single level.

        Parameters
        ----------
        name : str
            A key of :data:`FACTORS`.

        Returns
        -------
        Factor
            The factor.
        """
        for factor in self.factors:
            if factor.name == name:
                return factor
        return Factor(name, (FACTORS[name].default,))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | Path = "") -> CampaignSpec:
        """Build a spec from plain data (what a YAML, JSON or TOML file holds).

        Parameters
        ----------
        data : mapping
            Keys ``mode``, ``samples``, ``seed``, ``duration``, ``dt``, ``control_period``,
            ``divergence_radius`` and ``factors`` (a mapping of factor names to values).
        base_dir : str or Path
            Directory of relative ``csv:`` delay traces.

        Returns
        -------
        CampaignSpec
            The checked spec.
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"campaign spec must be a mapping of settings, got "
                             f"{type(data).__name__}")
        unknown = sorted(set(map(str, data)) - _SETTINGS)
        if unknown:
            raise ValueError(f"unknown campaign setting {unknown[0]!r}; known: "
                             f"{', '.join(sorted(_SETTINGS))}")
        raw = data.get("factors", {})
        if not isinstance(raw, Mapping):
            raise ValueError("campaign factors must be a mapping of factor names to values")
        factors = tuple(Factor.parse(str(name), value) for name, value in raw.items())
        settings = {key: data[key] for key in _SETTINGS - {"factors"} if key in data}
        return cls(factors=factors, base_dir=str(base_dir), **settings)

    @classmethod
    def from_file(cls, path: str | Path) -> CampaignSpec:
        """Read a spec from a YAML (``.yaml``, ``.yml``), JSON (``.json``) or TOML file.

        Parameters
        ----------
        path : str or Path
            The file; relative ``csv:`` traces are resolved against its directory.

        Returns
        -------
        CampaignSpec
            The checked spec.
        """
        path = Path(path)
        data = _read_spec_file(path)
        try:
            return cls.from_dict(data, base_dir=path.resolve().parent)
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (inverse of :meth:`from_dict`, without ``base_dir``)."""
        return {"mode": self.mode, "samples": self.samples, "seed": self.seed,
                "duration": self.duration, "dt": self.dt, "control_period": self.control_period,
                "divergence_radius": self.divergence_radius,
                "factors": {f.name: f.to_data() for f in self.factors}}

    def fingerprint(self) -> str:
        """SHA-256 of the spec and of the contents of its delay trace and policy files."""
        digest = hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode())
        for name, trace in sorted(self.traces().items()):
            digest.update(name.encode())
            digest.update(np.ascontiguousarray([trace.times, trace.delays]).tobytes())
        for name in sorted(self.policies()):
            digest.update(name.encode())
            digest.update(_trace_path(name, self.base_dir).read_bytes())
        return digest.hexdigest()

    @property
    def size(self) -> int:
        """Number of scenarios."""
        if self.mode == "random":
            return self.samples
        return math.prod(self.factor(name).size for name in FACTORS)

    def policies(self) -> dict[str, GainPolicy]:
        """The trained policies of the ``policy:`` controller levels, read now, keyed by level."""
        from teleopkit.agent import GainPolicy  # torch: only for campaigns with policies

        return {str(c): GainPolicy.load(_trace_path(str(c), self.base_dir))
                for c in self.factor("controller").levels if str(c).startswith("policy:")}

    def traces(self) -> dict[str, TraceDelay]:
        """The delay traces of the ``csv:`` levels, read now, keyed by the delay spec."""
        return {str(d): _read_trace(str(d), self.base_dir)
                for d in self.factor("delay").levels if str(d).startswith("csv:")}

    def expand(self) -> pd.DataFrame:
        """One row per scenario: ``scenario`` (0, 1, ...) and one column per factor.

        Returns
        -------
        pandas.DataFrame
            The scenarios in a fixed order (see the module docstring).
        """
        if self.size > MAX_SCENARIOS:
            raise ValueError(f"campaign has {self.size:,} scenarios, more than "
                             f"{MAX_SCENARIOS:,}")
        columns = self._grid() if self.mode == "grid" else self._random()
        table = pd.DataFrame(columns)
        table.insert(0, "scenario", np.arange(len(table), dtype=np.int64))
        return table.astype({name: _DTYPES[info.kind] for name, info in FACTORS.items()})

    def _grid(self) -> dict[str, list[Any]]:
        levels = [self.factor(name).levels for name in FACTORS]
        rows = list(itertools.product(*levels))
        return {name: [row[i] for row in rows] for i, name in enumerate(FACTORS)}

    def _random(self) -> dict[str, Any]:
        columns: dict[str, Any] = {}
        for index, name in enumerate(FACTORS):
            rng = np.random.default_rng([self.seed, index])
            given = any(f.name == name for f in self.factors)
            if name == "seed" and not given:
                columns[name] = rng.integers(0, 2**31, size=self.samples)
            else:
                columns[name] = self.factor(name).draw(rng, self.samples)
        return columns


_DTYPES = {"float": "float64", "int": "int64", "str": "str"}


def _read_spec_file(path: Path) -> Any:
    """Parse a spec file by its suffix into plain data."""
    suffix = path.suffix.lower()
    if suffix not in (".yaml", ".yml", ".json", ".toml"):
        raise ValueError(f"campaign spec {path} must be .yaml, .yml, .json or .toml")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        reason = getattr(error, "strerror", None) or str(error)
        raise ValueError(f"cannot read campaign spec {path}: {reason}") from None
    try:
        return _parse_text(text, suffix)
    except ValueError as error:
        first = str(error).strip().splitlines()[0] if str(error).strip() else "syntax error"
        raise ValueError(f"cannot parse campaign spec {path}: {first}") from None


def _parse_text(text: str, suffix: str) -> Any:
    if suffix == ".json":
        return json.loads(text)
    if suffix == ".toml":
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib  # type: ignore[no-redef]
        return tomllib.loads(text)
    try:
        import yaml
    except ModuleNotFoundError:
        raise ValueError("YAML specs need PyYAML (pip install 'teleopkit[campaign]')") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ValueError(f"{problem}{where}") from None


# --- scenario inputs ------------------------------------------------------------------------------


def _trace_path(spec: str, base_dir: str) -> Path:
    path = Path(spec.partition(":")[2]).expanduser()
    return path if path.is_absolute() or not base_dir else Path(base_dir) / path


def _read_trace(spec: str, base_dir: str) -> TraceDelay:
    return TraceDelay.from_csv(_trace_path(spec, base_dir))


def _check_controller(spec: str, base_dir: str) -> None:
    """Raise a one-line ValueError if ``spec`` is not ``fixed`` or a readable ``policy:PATH``."""
    if spec == "fixed":
        return
    if not (spec.startswith("policy:") and spec[7:]):
        raise ValueError(f"factor 'controller': values must be 'fixed' or policy:PATH, got "
                         f"{spec!r}")
    path = _trace_path(spec, base_dir)
    if not path.is_file():
        raise ValueError(f"factor 'controller': no policy file {path}")
    from teleopkit.agent import GainPolicy

    GainPolicy.load(path)


def _check_delay(spec: str, base_dir: str) -> None:
    """Raise a one-line ValueError if ``spec`` is not a delay spec (reads csv traces)."""
    if spec.startswith("csv:") and spec[4:]:
        _read_trace(spec, base_dir)
    else:
        parse_delay(spec, np.random.default_rng(0))


def _reference_gains(spec: str, n_joints: int, drawn: np.ndarray | None) -> np.ndarray:
    """Reference gains ``(n,)`` of a ``reference_gain`` level (``drawn`` for ``random``)."""
    if spec == "random":
        return drawn if drawn is not None else np.ones(n_joints)
    try:
        values = [float(v) for v in spec.split(",")]
    except ValueError:
        raise ValueError(f"factor 'reference_gain': values must be 'random', a number or "
                         f"G1,G2, got {spec!r}") from None
    if len(values) == 1:
        values *= n_joints
    if len(values) != n_joints or not all(math.isfinite(v) for v in values):
        raise ValueError(f"factor 'reference_gain': need 1 or {n_joints} finite values, got "
                         f"{spec!r}")
    return np.array(values)


def _delay_pair(spec: str, rng: np.random.Generator,
                traces: Mapping[str, TraceDelay]) -> tuple[DelayProfile, DelayProfile]:
    if spec in traces:
        return traces[spec], traces[spec]
    return parse_delay(spec, rng)


def _model_params(row: Mapping[str, Any]) -> TeleoperatorParams:
    """The paper's teleoperator with the row's model factors."""
    base = paper_setup()
    n = base.n_joints

    def arm(source: PlanarArm, scale: float) -> PlanarArm:
        return PlanarArm(source.lengths, tuple(scale * m for m in source.masses))

    return replace(
        base,
        local_arm=arm(base.local_arm, float(row["local_mass_scale"])),
        remote_arm=arm(base.remote_arm, float(row["remote_mass_scale"])),
        joints=ElasticJoints((float(row["joint_stiffness"]),) * n,
                             (float(row["rotor_inertia"]),) * n),
        local_gains=PDGains.uniform(float(row["kl"]), float(row["bl"]), n))


# --- simulation of a chunk ------------------------------------------------------------------------


@dataclass(frozen=True)
class ChunkTask:
    """What one Dask task simulates.

    Parameters
    ----------
    chunk : int
        Chunk id.
    rows : pandas.DataFrame
        The chunk's rows of :meth:`CampaignSpec.expand`.
    duration, dt, control_period, divergence_radius : float
        Episode settings of the spec.
    policies : mapping of str to GainPolicy
        The trained policies of the chunk's ``policy:`` controllers, keyed by level.
    """

    chunk: int
    rows: pd.DataFrame
    duration: float
    dt: float
    control_period: float
    divergence_radius: float
    policies: Mapping[str, GainPolicy] = field(default_factory=dict)


class _RunningMetrics:
    """Trapezoidal integrals and maxima of the error norms, accumulated period by period."""

    def __init__(self, state: np.ndarray) -> None:
        n = state.shape[1] // 8
        self.n = n
        self.t = 0.0
        self.last = self._norms(state, state[:, :n])
        self.sums = np.zeros((4, state.shape[0]))  # int |e_t|^2, int |e_t|, int |e_d|^2, |e_d|
        self.maxima = self.last.copy()
        self.finite = np.all(np.isfinite(state), axis=1)
        self.magnitude: list[np.ndarray] = []

    def _norms(self, state: np.ndarray, delayed_ql: np.ndarray) -> np.ndarray:
        n = self.n
        theta = state[..., 4 * n:5 * n]
        return np.stack([np.linalg.norm(theta - delayed_ql, axis=-1),
                         np.linalg.norm(theta - state[..., 2 * n:3 * n], axis=-1)])

    def add(self, step: StepResult) -> None:
        """Accumulate the periods of ``step``."""
        n = self.n
        norms = self._norms(step.state, step.delayed[..., 0, :])  # (2, P, B)
        values = np.concatenate([self.last[:, None], norms], axis=1)
        widths = np.diff(np.concatenate([[self.t], step.t]))[:, None]
        for k, power in enumerate((2, 1, 2, 1)):
            series = values[k // 2] ** power
            self.sums[k] += np.sum(0.5 * (series[1:] + series[:-1]) * widths, axis=0)
        self.maxima = np.fmax(self.maxima, norms.max(axis=1))
        self.finite &= np.all(np.isfinite(step.state), axis=(0, 2))
        positions = np.abs(step.state[..., np.r_[0:n, 2 * n:3 * n, 4 * n:5 * n]])
        self.magnitude.append(np.nan_to_num(positions, nan=np.inf).max(axis=-1))
        self.t, self.last = float(step.t[-1]), norms[:, -1]

    def frame(self, radius: float) -> pd.DataFrame:
        """The metric columns, one row per scenario."""
        magnitude = np.concatenate(self.magnitude)
        quarter = max(1, magnitude.shape[0] // 4)
        with np.errstate(divide="ignore", invalid="ignore"):
            growth = (magnitude[-quarter:].max(axis=0)
                      / magnitude[quarter:2 * quarter].max(axis=0))
        columns = {"rms_track": np.sqrt(self.sums[0] / self.t), "iae_track": self.sums[1],
                   "max_track": self.maxima[0], "rms_damp": np.sqrt(self.sums[2] / self.t),
                   "iae_damp": self.sums[3], "max_damp": self.maxima[1]}
        for name, values in columns.items():
            columns[name] = np.where(self.finite, values, np.inf)
        peak = magnitude.max(axis=0)
        growing = ((growth > 1.0) & (magnitude[-quarter:].max(axis=0) > GROWTH_FLOOR)
                   & (self.t >= GROWTH_MIN_DURATION))
        columns |= {"max_position": peak, "growth": growth,
                    "diverged": ~self.finite | (peak > radius) | growing}
        return pd.DataFrame(columns)


def _scenario_inputs(row: Mapping[str, Any], n: int, traces: Mapping[str, TraceDelay],
                     ) -> tuple[DelayProfile, DelayProfile, np.ndarray]:
    """Forward and backward delays and reference gains of one row, drawn from its seed."""
    rng = np.random.default_rng(int(row["seed"]))
    drawn = sample_reference_gains(rng, 1, n)[0]
    reference = _reference_gains(str(row["reference_gain"]), n, drawn)
    forward, backward = _delay_pair(str(row["delay"]), rng, traces)
    scale = float(row["delay_scale"])
    return scale_delay(forward, scale), scale_delay(backward, scale), reference


def _simulate_group(task: ChunkTask, rows: pd.DataFrame,
                    traces: Mapping[str, TraceDelay]) -> pd.DataFrame:
    """Simulate scenarios sharing one teleoperator as one batch."""
    start = time.perf_counter()
    records = [{str(k): v for k, v in record.items()} for record in rows.to_dict("records")]
    params = _model_params(records[0])
    n = params.n_joints
    forward, backward, reference = zip(*(_scenario_inputs(row, n, traces)
                                         for row in records), strict=True)
    scenario = Scenario(params, stack_delays(forward), stack_delays(backward),
                        np.array(reference))
    sim = Simulator(scenario, task.dt, task.control_period)
    controller = str(records[0]["controller"])
    if controller == "fixed":
        gains = np.repeat(rows[["kr", "br"]].to_numpy(dtype=float), n, axis=1)
        metrics = _run(sim, gains, task)
    else:
        layer = SafetyLayer.from_certificate(default_certificate(params), task.control_period)
        metrics = _run_policy(sim, task.policies[controller], layer, task)
    out = rows.reset_index(drop=True)
    for i in range(n):
        out[f"G_{i + 1}"] = scenario.reference_gains[:, i]
    out["delay_bound"] = [max(f.bound, b.bound) for f, b in zip(forward, backward, strict=True)]
    out = pd.concat([out, metrics], axis=1)
    out["wall_time"] = (time.perf_counter() - start) / len(rows)
    return out


def _run(sim: Simulator, gains: np.ndarray, task: ChunkTask) -> pd.DataFrame:
    """Simulate ``task.duration`` seconds in one-second blocks, accumulating the metrics."""
    periods = max(1, round(task.duration / task.control_period))
    block = max(1, round(1.0 / task.control_period))
    metrics = _RunningMetrics(sim.state)
    for first in range(0, periods, block):
        count = min(block, periods - first)
        metrics.add(sim.advance(np.broadcast_to(gains, (count, *gains.shape))))
    return metrics.frame(task.divergence_radius)


def _run_policy(sim: Simulator, policy: GainPolicy, layer: SafetyLayer,
                task: ChunkTask) -> pd.DataFrame:
    """Simulate ``task.duration`` seconds with the policy choosing projected gains per period."""
    periods = max(1, round(task.duration / task.control_period))
    state = sim.state
    n = state.shape[1] // 8
    metrics = _RunningMetrics(state)
    delayed, applied = state[:, :n], None
    for _ in range(periods):
        raw = policy(np.nan_to_num(observation(state, delayed, n)))
        applied = layer.project_batch(raw, applied).action
        result = sim.advance(applied[None])
        metrics.add(result)
        state, delayed = result.state[0], result.delayed[0, :, 0]
    return metrics.frame(task.divergence_radius)


def simulate_chunk(task: ChunkTask,
                   traces: Mapping[str, TraceDelay] | None = None) -> pd.DataFrame:
    """Simulate one chunk of scenarios (the body of a Dask task).

    Scenarios sharing a teleoperator run as one batch of the simulator, single-threaded (the
    workers provide the parallelism).

    Parameters
    ----------
    task : ChunkTask
        The chunk.
    traces : mapping of str to TraceDelay, optional
        The campaign's delay traces (:meth:`CampaignSpec.traces`), needed when a row's delay is
        ``csv:PATH``.

    Returns
    -------
    pandas.DataFrame
        The chunk's rows with the result columns, sorted by ``scenario``.
    """
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        groups = task.rows.groupby([*MODEL_FACTORS, "controller"], sort=False)
        parts = [_simulate_group(task, rows, traces or {}) for _, rows in groups]
    finally:
        numba.set_num_threads(threads)
    table = pd.concat(parts, ignore_index=True).sort_values("scenario", ignore_index=True)
    table.insert(1, "chunk", np.int64(task.chunk))
    return table


def plan_chunks(scenarios: pd.DataFrame, chunk: int) -> list[np.ndarray]:
    """Cut the scenarios into chunks of at most ``chunk`` rows, grouped by teleoperator.

    Rows are ordered by their model factors (stably), so a chunk holds as few distinct
    teleoperators as possible.

    Parameters
    ----------
    scenarios : pandas.DataFrame
        Output of :meth:`CampaignSpec.expand`.
    chunk : int
        Largest number of scenarios per chunk.

    Returns
    -------
    list of ndarray
        The sorted ``scenario`` ids of each chunk; chunk ``k`` is the ``k``-th entry.
    """
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise ValueError(f"chunk must be an integer >= 1, got {chunk!r}")
    ordered = scenarios.sort_values(list(MODEL_FACTORS), kind="stable")["scenario"].to_numpy()
    return [np.sort(ordered[i:i + chunk]) for i in range(0, len(ordered), chunk)]


# --- chunk store ----------------------------------------------------------------------------------


class _ChunkStore:
    """Chunk files ``chunk-000000.parquet`` and a manifest in ``<out>.chunks/``."""

    def __init__(self, out: Path) -> None:
        self.dir = out.with_name(out.name + ".chunks")

    def path(self, chunk: int) -> Path:
        return self.dir / f"chunk-{chunk:06d}.parquet"

    def prepare(self, manifest: dict[str, Any], resume: bool) -> None:
        """Create the directory; check (resume) or reset (no resume) what is there."""
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.dir / "manifest.json"
        if resume and path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError):
                old = None
            if old != json.loads(json.dumps(manifest)):
                raise ValueError(f"{self.dir} holds chunks of another campaign or chunk size; "
                                 "use another output or delete it")
            return
        for stale in self.dir.glob("chunk-*.parquet"):
            stale.unlink()
        _atomic_write(path, lambda tmp: tmp.write_text(json.dumps(manifest, indent=2)))

    def load(self, chunk: int, ids: np.ndarray) -> pd.DataFrame | None:
        """The chunk's table if its file exists, is readable and holds exactly ``ids``."""
        path = self.path(chunk)
        if not path.exists():
            return None
        try:
            table = pd.read_parquet(path)
        except ImportError:
            raise
        except Exception:  # a damaged file (pyarrow raises its own error classes): run again
            return None
        if "scenario" not in table or not np.array_equal(table["scenario"].to_numpy(), ids):
            return None
        return table

    def save(self, chunk: int, table: pd.DataFrame) -> None:
        _atomic_write(self.path(chunk), lambda tmp: table.to_parquet(tmp, index=False))


def _atomic_write(path: Path, write: Callable[[Path], Any]) -> None:
    """Write through a temporary file in the same directory, then rename."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


# --- execution ------------------------------------------------------------------------------------


def _tasks(spec: CampaignSpec, scenarios: pd.DataFrame, chunks: Sequence[np.ndarray],
           todo: Iterable[int]) -> list[ChunkTask]:
    indexed = scenarios.set_index("scenario", drop=False)
    policies = spec.policies()
    tasks = []
    for k in todo:
        rows = indexed.loc[chunks[k]].reset_index(drop=True)
        used = {c: policies[c] for c in rows["controller"].unique() if c in policies}
        tasks.append(ChunkTask(k, rows, spec.duration, spec.dt, spec.control_period,
                               spec.divergence_radius, used))
    return tasks


def _run_synchronous(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
                     done: Callable[[pd.DataFrame], None]) -> None:
    import dask

    for task in tasks:
        done(dask.delayed(simulate_chunk)(task, traces).compute(scheduler="synchronous"))


class CampaignInterrupted(RuntimeError):
    """The cluster lost a chunk for good (its workers kept dying); resume to finish."""


def _run_distributed(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
                     client: Client, done: Callable[[pd.DataFrame], None]) -> None:
    from distributed import KilledWorker, as_completed

    shared = client.scatter(dict(traces), broadcast=True) if traces else {}  # sent once
    futures = [client.submit(simulate_chunk, task, shared, pure=False) for task in tasks]
    try:
        for future in as_completed(futures):
            done(future.result())
    except KilledWorker as error:
        raise CampaignInterrupted(
            f"campaign stopped: {error}; the finished chunks are kept, run again with "
            "resume=True (teleopkit campaign --resume) to finish it") from None
    finally:
        client.cancel(futures)


def _usable_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def local_cluster(workers: int | None = None) -> Any:
    """A Dask LocalCluster of single-threaded worker processes on this machine.

    What :func:`run_campaign` starts when no client is given; start one yourself to run several
    campaigns on the same workers (``Client(local_cluster())``).

    Parameters
    ----------
    workers : int, optional
        Worker processes; the number of usable cores by default.

    Returns
    -------
    distributed.LocalCluster
        Processes with one thread each and no dashboard (with Dask's one-thread defaults for
        OpenMP, MKL and OpenBLAS); each task runs numba on one thread
        (:func:`simulate_chunk`). ``NUMBA_NUM_THREADS`` is deliberately not set through Dask:
        its nanny would also set it in this process, where numba then refuses to compile once
        its threads run with another count.
    """
    from distributed import LocalCluster

    count = workers if workers is not None else _usable_cores()
    return LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                        dashboard_address=None)


def _execute(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
             client: Client | str | None, workers: int | None,
             done: Callable[[pd.DataFrame], None]) -> None:
    """Run the tasks on the chosen scheduler, handing each finished chunk to ``done``."""
    try:
        import dask  # noqa: F401
        from distributed import Client
    except ModuleNotFoundError:
        raise ModuleNotFoundError("campaigns need dask[distributed]: pip install "
                                  "'teleopkit[campaign]'") from None
    if client == "synchronous":
        _run_synchronous(tasks, traces, done)
    elif client is None:
        with local_cluster(workers) as cluster, Client(cluster) as local:
            _run_distributed(tasks, traces, local, done)
    elif isinstance(client, str):
        with Client(client) as remote:
            _run_distributed(tasks, traces, remote, done)
    else:
        _run_distributed(tasks, traces, client, done)


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="scenario", disable=not enabled, leave=False)


def _load_spec(spec: CampaignSpec | Mapping[str, Any] | str | Path) -> CampaignSpec:
    if isinstance(spec, CampaignSpec):
        return spec
    if isinstance(spec, Mapping):
        return CampaignSpec.from_dict(spec)
    return CampaignSpec.from_file(spec)


def _check_output(out: str | Path) -> Path:
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".csv"):
        raise ValueError(f"campaign output {out} must end in .parquet or .csv")
    if out.is_dir():
        raise ValueError(f"campaign output {out} is a directory")
    return out


def _write_table(table: pd.DataFrame, out: Path) -> None:
    if out.suffix.lower() == ".csv":
        _atomic_write(out, lambda tmp: table.to_csv(tmp, index=False))
    else:
        _atomic_write(out, lambda tmp: table.to_parquet(tmp, index=False))


def run_campaign(spec: CampaignSpec | Mapping[str, Any] | str | Path, out: str | Path,
                 client: Client | str | None = None, chunk: int = 64, resume: bool = True,
                 workers: int | None = None, progress: bool = False) -> pd.DataFrame:
    """Run a campaign on Dask and return (and save) one row per scenario.

    Parameters
    ----------
    spec : CampaignSpec, mapping, str or Path
        The campaign, its plain data, or a YAML / JSON / TOML file.
    out : str or Path
        Result table, ``.parquet`` or ``.csv``. Finished chunks are kept as Parquet files in the
        directory ``<out>.chunks`` (with a manifest of the spec), so that a rerun resumes.
    client : distributed.Client, str or None
        ``None``: a LocalCluster of ``workers`` single-threaded processes on this machine, made
        and closed here; a scheduler address (``"tcp://host:8786"``): that cluster (the workers
        need teleopkit installed); a ``distributed.Client``: used as it is; ``"synchronous"``:
        Dask's synchronous scheduler in this process (debugging, tests).
    chunk : int
        Scenarios per task (simulated as batches of the simulator).
    resume : bool
        Keep the chunk files of an earlier run of the same spec and chunk size and run only the
        missing chunks; with ``False`` start afresh (deleting earlier chunk files).
    workers : int, optional
        Worker processes of the default LocalCluster; the number of usable cores by default.
    progress : bool
        Show a progress bar (standard error).

    Returns
    -------
    pandas.DataFrame
        One row per scenario, sorted by ``scenario``: ``scenario``, ``chunk``, the factor columns
        of :data:`FACTORS`, ``G_1, G_2`` (operator reference gains), ``delay_bound`` and
        :data:`METRIC_COLUMNS`.

    Raises
    ------
    ValueError
        A bad spec, output path or chunk size, or chunk files of another campaign in the way.
    CampaignInterrupted
        The cluster gave up on a chunk (see Notes); the finished chunks are kept.

    Notes
    -----
    If a Dask worker process dies mid-campaign, Dask reruns the chunks it held on the other (or
    restarted) workers and the table is unchanged; only a chunk whose workers die more than
    ``distributed.scheduler.allowed-failures`` times (3 by default) stops the run with
    :class:`CampaignInterrupted`, and a rerun with ``resume=True`` then runs only the chunks
    missing from ``<out>.chunks``.
    """
    spec = _load_spec(spec)
    out = _check_output(out)
    scenarios = spec.expand()
    chunks = plan_chunks(scenarios, chunk)
    store = _ChunkStore(out)
    store.prepare({"fingerprint": spec.fingerprint(), "chunk": int(chunk),
                   "scenarios": len(scenarios), "spec": spec.to_dict()}, resume)
    tables = {k: store.load(k, ids) for k, ids in enumerate(chunks)} if resume else {}
    todo = [k for k in range(len(chunks)) if tables.get(k) is None]
    with _progress(len(scenarios), progress) as bar:
        bar.update(len(scenarios) - sum(len(chunks[k]) for k in todo))

        def done(table: pd.DataFrame) -> None:
            k = int(table["chunk"].iloc[0])
            store.save(k, table)
            tables[k] = table
            bar.update(len(table))

        if todo:
            _execute(_tasks(spec, scenarios, chunks, todo), spec.traces(), client, workers,
                     done)
    table = _assemble([tables[k] for k in range(len(chunks))], len(scenarios))
    _write_table(table, out)
    return table


def _assemble(parts: Sequence[pd.DataFrame | None], size: int) -> pd.DataFrame:
    """Concatenate the chunks; check one row per scenario."""
    table = pd.concat(parts, ignore_index=True).sort_values("scenario", ignore_index=True)
    table = table.astype({name: _DTYPES[info.kind] for name, info in FACTORS.items()})
    if not np.array_equal(table["scenario"].to_numpy(), np.arange(size)):
        raise RuntimeError("campaign table is incomplete or has duplicate scenarios")
    return table
