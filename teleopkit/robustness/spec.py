"""Campaign specs: settings and factors from plain data or a YAML, JSON or TOML file.

Each factor is written in the spec as a single value (fixed), a list of levels, ``{linspace: [LO,
HI, N]}`` or ``{range: [START, STOP]}`` (levels), or, in ``mode: random`` only, ``{uniform: [LO,
HI]}`` or ``{loguniform: [LO, HI]}``. A grid crosses all levels (the parameter factors outermost,
``seed`` innermost); a random campaign draws ``samples`` scenarios, each factor from its own
generator seeded by the spec's ``seed`` and the factor's position in :data:`FACTORS` (levels are
drawn uniformly), and a ``seed`` per scenario unless the ``seed`` factor is given.

Reproducibility: a row is reproduced from its own columns. Its randomness comes from
``numpy.random.default_rng(seed)`` in the order of :func:`teleopkit.sim.simulator.simulate`
(reference gains first, then the delay profile's draws), so with default parameters and
``delay_scale = 1`` a
row matches ``simulate((kr, br), duration, delay, seed)``. Rows do not depend on the chunk size,
the number of workers or the scheduler, except ``wall_time`` and ``chunk``.

A campaign varies a setup (:class:`~teleopkit.setup.Setup`; the paper's by default, or the key
``setup: FILE`` relative to the spec, or ``teleopkit campaign --setup FILE``): the model factors
change its plant (left out, they keep the setup's own values, shown in their columns when the
same on every joint, else NaN), each row draws the setup's operator motion and start from its
seed, and the delay level ``setup`` (the default for a setup other than the paper's) draws the
setup's network.

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
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from teleopkit.delays.profiles import TraceDelay
from teleopkit.delays.spec import check_trace_ends, parse_delay
from teleopkit.rl.policy import GainPolicy
from teleopkit.robustness.factors import FACTORS, Factor, factor_dtypes
from teleopkit.setup import Setup
from teleopkit.sim.divergence import DIVERGENCE_RADIUS
from teleopkit.sim.timing import CONTROL_PERIOD, DEFAULT_DT, periods, substeps

__all__ = ["MAX_SCENARIOS", "CampaignSpec", "reference_gains", "resolve"]

MAX_SCENARIOS = 10_000_000
"""Largest campaign :meth:`CampaignSpec.expand` accepts."""

_SETTINGS = {"mode", "samples", "seed", "duration", "dt", "control_period", "divergence_radius",
             "factors", "setup"}


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
        Episode length in seconds (a whole number of control periods): the setup's recorded
        operator motion (if any) must last it, and every row's delays must be shorter
        (:func:`~teleopkit.robustness.chunks.check_row_delays`, before a run).
    dt : float
        Integration step in seconds.
    control_period : float
        Gain hold period in seconds (a multiple of ``dt``).
    divergence_radius : float
        Position magnitude (rad) that counts as divergence.
    base_dir : str
        Directory against which ``csv:PATH`` delay traces are resolved (the spec file's).
    setup : Setup
        The setup the factors vary (the paper's by default).

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
    control_period: float = CONTROL_PERIOD
    divergence_radius: float = DIVERGENCE_RADIUS
    base_dir: str = ""
    setup: Setup = field(default_factory=Setup.paper)
    _traces: dict[str, TraceDelay] = field(init=False, repr=False, compare=False,
                                           default_factory=dict)
    _policies: dict[str, GainPolicy] = field(init=False, repr=False, compare=False,
                                             default_factory=dict)

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
        try:
            substeps(self.control_period, self.dt)
            periods(self.duration, self.control_period)
        except ValueError as error:
            raise ValueError(f"campaign {error}") from None
        for gain in self.factor("reference_gain").levels:
            reference_gains(str(gain), self.setup.n_joints, None)
        try:
            self.setup.operator.motion.check_ends(self.duration)
        except ValueError as error:
            raise ValueError(f"setup operator.motion: {error}") from None
        # the files a campaign needs are read once, here: bad ones are refused before a run
        object.__setattr__(self, "_traces", {
            str(d): _read_trace(str(d), self.base_dir, self.duration)
            for d in self.factor("delay").levels
            if _check_delay(str(d))})
        object.__setattr__(self, "_policies", {
            str(c): _read_policy(str(c), self.base_dir)
            for c in self.factor("controller").levels if _is_policy(str(c))})

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
            ``divergence_radius``, ``factors`` (a mapping of factor names to values) and
            ``setup`` (a setup file relative to ``base_dir``).
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
        settings = {key: data[key] for key in _SETTINGS - {"factors", "setup"} if key in data}
        if "setup" in data:
            settings["setup"] = Setup.from_file(resolve(f"setup:{data['setup']}", str(base_dir)))
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
        """Plain-data form (inverse of :meth:`from_dict`, without ``base_dir`` and the setup)."""
        return {"mode": self.mode, "samples": self.samples, "seed": self.seed,
                "duration": self.duration, "dt": self.dt, "control_period": self.control_period,
                "divergence_radius": self.divergence_radius,
                "factors": {f.name: f.to_data() for f in self.factors}}

    def fingerprint(self) -> str:
        """SHA-256 of the spec, its setup and the contents of its delay trace and policy files."""
        digest = hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode())
        if self.setup != Setup.paper():  # the paper's: the fingerprints of earlier campaigns
            digest.update(self.setup.fingerprint.encode())
        for name, trace in sorted(self.traces().items()):
            digest.update(name.encode())
            digest.update(np.ascontiguousarray([trace.times, trace.delays]).tobytes())
        for name in sorted(self.policies()):
            digest.update(name.encode())
            digest.update(resolve(name, self.base_dir).read_bytes())
        return digest.hexdigest()

    @property
    def size(self) -> int:
        """Number of scenarios."""
        if self.mode == "random":
            return self.samples
        return math.prod(self.factor(name).size for name in FACTORS)

    def policies(self) -> dict[str, GainPolicy]:
        """The trained policies of the ``policy:`` controller levels, keyed by level."""
        return dict(self._policies)

    def traces(self) -> dict[str, TraceDelay]:
        """The delay traces of the ``csv:`` levels, keyed by the delay spec."""
        return dict(self._traces)

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
        return self._setup_defaults(table).astype(factor_dtypes())

    def _setup_defaults(self, table: pd.DataFrame) -> pd.DataFrame:
        """Columns of the factors left out: the setup's own values where they differ."""
        if self.setup == Setup.paper():
            return table
        given = {factor.name for factor in self.factors}
        params = self.setup.params
        values = {"joint_stiffness": params.joints.stiffness,
                  "rotor_inertia": params.joints.rotor_inertia,
                  "kl": params.local_gains.stiffness, "bl": params.local_gains.damping}
        for name, per_joint in values.items():
            if name not in given:
                table[name] = per_joint[0] if len(set(per_joint)) == 1 else np.nan
        if "delay" not in given:
            table["delay"] = "setup"
        return table

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


def resolve(spec: str, base_dir: str) -> Path:
    """The file of a ``csv:PATH`` or ``policy:PATH`` level, relative to the spec's directory.

    Parameters
    ----------
    spec : str
        The level, ``KIND:PATH``.
    base_dir : str
        Directory of the spec file (empty: the working directory).

    Returns
    -------
    Path
        ``PATH`` itself if absolute, else ``base_dir / PATH``.
    """
    path = Path(spec.partition(":")[2]).expanduser()
    return path if path.is_absolute() or not base_dir else Path(base_dir) / path


def _read_trace(spec: str, base_dir: str, duration: float) -> TraceDelay:
    """The trace of a ``csv:PATH`` level, refused if it cannot drive a whole run."""
    trace = TraceDelay.from_csv(resolve(spec, base_dir))
    try:
        check_trace_ends((trace, trace), duration)
    except ValueError as error:
        raise ValueError(f"factor 'delay': {spec}: {error}") from None
    return trace


def _is_policy(spec: str) -> bool:
    """Whether a controller level is ``policy:PATH`` (``False`` for ``fixed``); else raise."""
    if spec == "fixed":
        return False
    if not (spec.startswith("policy:") and spec[7:]):
        raise ValueError(f"factor 'controller': values must be 'fixed' or policy:PATH, got "
                         f"{spec!r}")
    return True


def _read_policy(spec: str, base_dir: str) -> GainPolicy:
    path = resolve(spec, base_dir)
    if not path.is_file():
        raise ValueError(f"factor 'controller': no policy file {path}")
    return GainPolicy.load(path)


def _check_delay(spec: str) -> bool:
    """Whether a delay level is a ``csv:PATH`` trace; raise if it is no delay spec at all."""
    if spec.startswith("csv:") and spec[4:]:
        return True
    if spec == "setup":  # the setup's network
        return False
    parse_delay(spec, np.random.default_rng(0))
    return False


def reference_gains(spec: str, n_joints: int, drawn: np.ndarray | None) -> np.ndarray:
    """Operator reference gains of a ``reference_gain`` level.

    Parameters
    ----------
    spec : str
        ``random``, one number for every joint, or one number per joint separated by commas.
    n_joints : int
        Number of joints.
    drawn : ndarray, shape (n,), optional
        The gains drawn from the row's seed, used for ``random`` (ones when missing).

    Returns
    -------
    ndarray, shape (n,)
        The reference gains ``G``.
    """
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
