"""A whole teleoperation setup as one frozen value: plant, network, operator and start.

A setup file (YAML; JSON is YAML too) describes what the toolkit's commands need to know about
a user's teleoperator::

    plant:
      local_arm:   {lengths: [0.38, 0.38], masses: [0.5, 0.35]}   # optional com, inertia
      remote_arm:  {lengths: [0.38, 0.38], masses: [0.5, 0.35]}  # or {min: [..], max: [..]}
      joints:      {stiffness: [100, 100], rotor_inertia: [0.3, 0.3]}  # ranges too
      local_gains: {stiffness: [25, 25], damping: [10, 10]}
      environment: free            # or {wall: [0.5, .inf], stiffness: 1000, damping: 5}
      torque_limit: 300            # N m; .inf for none
    network:
      forward:  {min: 0.0, max: 1.0, profile: paper}   # any delay spec, or a list of them
      backward: {min: 0.0, max: 1.0, profile: paper}
    operator: {stiffness: 10, damping: 2, motion: paper}
    start: paper

Only ``plant.local_arm`` is required: left-out entries take the paper's values (sized to the
arm's joints where the paper's have two). ``plant`` may also be a list of plants (the same
number of joints), each scenario running one of them drawn uniformly: a heavier or softer remote
arm, a wall. The remote arm's and the joints' values may be ranges, ``{min: [...], max: [...]}``
per joint (:class:`~teleopkit.model.plant_range.PlantRange`): each scenario draws them
uniformly, around the nominal plant of their midpoints. The paper's setup ships as
``paper_setup.yaml`` (:data:`PAPER_SETUP_FILE`).

A wall is one position per joint in radians, not a range: joint ``i`` is pushed back once
``q_r,i`` exceeds it (``.inf``: no wall on that joint; ``-.inf`` is refused). A wall too stiff
for the integration step is refused when a run starts
(:func:`~teleopkit.sim.stability.check_step` names a step and the stiffest wall it
integrates). A recorded motion (``csv:PATH``) must last as long as each run it drives.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from teleopkit.model.params import ElasticJoints, PDGains, PlanarArm, TeleoperatorParams, Wall
from teleopkit.model.plant_range import Interval, PlantRange
from teleopkit.model.records import PLANT_LABELS, json_ready
from teleopkit.setup.network import Channel, Network, spec_reach
from teleopkit.setup.operator import MotionSpec, OperatorSetup
from teleopkit.setup.reading import Node, SetupError, listed, load_document
from teleopkit.setup.start import StartMix, StartSpec

if TYPE_CHECKING:
    from teleopkit.delays.profiles import DelayProfile
    from teleopkit.sim.scenarios import Scenario

__all__ = ["PAPER_SETUP_FILE", "SHIPPED_SETUPS", "Setup", "paper_setup_path", "shipped_setup_path"]

PAPER_SETUP_FILE = "paper_setup.yaml"
"""Name of the paper's setup file among the package's data (``teleopkit/data``)."""

_PAPER = TeleoperatorParams()


def _per_joint(node: Node | None, default: tuple[float, ...], n: int,
               ranges: dict[str, Interval] | None = None, name: str = "", **checks: Any
               ) -> tuple[float, ...]:
    """A per-joint entry, or the paper's value (its first entry repeated for other sizes)."""
    if node is not None:
        return _numbers(node, n, ranges, name, **checks)
    return default if len(default) == n else (default[0],) * n


def _numbers(node: Node, n: int | None, ranges: dict[str, Interval] | None, name: str,
             **checks: Any) -> tuple[float, ...]:
    """Per-joint numbers; where ``ranges`` is given also ``{min, max}`` of them.

    A range is recorded in ``ranges[name]`` and its midpoints returned (the nominal plant).
    """
    if not isinstance(node.value, dict):
        return node.numbers(n, **checks)
    if ranges is None:
        raise node.error("a range ({min, max}) is for the remote arm and the joints only")
    entries = node.fields(("min", "max"), ("min", "max"))
    low = entries["min"].numbers(n, **checks)
    high = entries["max"].numbers(len(low), **checks)
    if any(h < lo for lo, h in zip(low, high, strict=True)):
        raise node.error(f"max {listed(high)} is below min {listed(low)}")
    ranges[name] = (low, high)
    return tuple((lo + h) / 2 for lo, h in zip(low, high, strict=True))


def _arm(node: Node, n: int | None, ranges: dict[str, Interval] | None = None,
         part: str = "") -> PlanarArm:
    entries = node.fields(("lengths", "masses", "com", "inertia"), ("lengths", "masses"))
    lengths = _numbers(entries["lengths"], n, ranges, f"{part}.lengths", minimum=0.0,
                       strict=True)
    masses = _numbers(entries["masses"], len(lengths), ranges, f"{part}.masses", minimum=0.0,
                      strict=True)
    extra = {key: _numbers(entries[key], len(lengths), ranges, f"{part}.{key}", minimum=0.0)
             for key in ("com", "inertia") if key in entries}
    try:
        return PlanarArm(lengths, masses, **extra)
    except (TypeError, ValueError) as error:
        raise node.error(str(error)) from None


def _environment(node: Node | None, n: int) -> Any:
    if node is None or node.value == "free":
        return "free"
    if not isinstance(node.value, dict):
        raise node.error(f"must be free or {{wall: [positions], stiffness, damping}}, got "
                         f"{node.value!r}")
    entries = node.fields(("wall", "stiffness", "damping"), ("wall",))
    position = entries["wall"].numbers(n, allow_inf=True)
    stiffness = entries["stiffness"].number(0.0) if "stiffness" in entries else 1000.0
    damping = entries["damping"].number(0.0) if "damping" in entries else 5.0
    try:
        return Wall(position, stiffness, damping)
    except ValueError as error:  # a wall at -inf
        raise entries["wall"].error(str(error)) from None


def _plant(node: Node) -> tuple[dict[str, Any], PlantRange]:
    """The model's parts from a ``plant`` entry (ranged values at their midpoints); its ranges."""
    entries = node.fields(("local_arm", "remote_arm", "joints", "local_gains", "environment",
                           "torque_limit"), ("local_arm",))
    local = _arm(entries["local_arm"], None)
    n = local.n_joints
    ranges: dict[str, Interval] = {}
    remote = _arm(entries["remote_arm"], n, ranges, "remote_arm") if "remote_arm" in entries \
        else local
    joints = entries["joints"].fields(("stiffness", "rotor_inertia")) if "joints" in entries \
        else {}
    gains = entries["local_gains"].fields(("stiffness", "damping")) if "local_gains" in entries \
        else {}
    limit = entries.get("torque_limit")
    parts = {
        "local_arm": local, "remote_arm": remote,
        "joints": ElasticJoints(*(
            _per_joint(joints.get(key), getattr(_PAPER.joints, key), n, ranges, f"joints.{key}",
                       minimum=0.0, strict=True) for key in ("stiffness", "rotor_inertia"))),
        "local_gains": PDGains(
            _per_joint(gains.get("stiffness"), _PAPER.local_gains.stiffness, n, minimum=0.0),
            _per_joint(gains.get("damping"), _PAPER.local_gains.damping, n, minimum=0.0)),
        "environment": _environment(entries.get("environment"), n),
        "torque_limit": limit.number(0.0, strict=True, allow_inf=True) if limit is not None
        else _PAPER.torque_limit,
    }
    return parts, PlantRange(ranges)


def _plant_data(p: TeleoperatorParams, ranges: PlantRange) -> dict[str, Any]:
    """A plant as a ``plant`` entry (every key written out; a ranged value as ``{min, max}``)."""

    def values(name: str, value: tuple[float, ...]) -> Any:
        if name in ranges.bounds:
            low, high = ranges.bounds[name]
            return {"min": list(low), "max": list(high)}
        return list(value)

    def arm(value: PlanarArm, part: str) -> dict[str, Any]:
        return {key: values(f"{part}.{key}", item) for key, item in asdict(value).items()
                if item is not None}

    environment: Any = "free"
    if isinstance(p.environment, Wall):
        environment = {"wall": list(p.environment.position),
                       "stiffness": p.environment.stiffness, "damping": p.environment.damping}
    return {"local_arm": arm(p.local_arm, "local_arm"),
            "remote_arm": arm(p.remote_arm, "remote_arm"),
            "joints": {key: values(f"joints.{key}", getattr(p.joints, key))
                       for key in ("stiffness", "rotor_inertia")},
            "local_gains": {"stiffness": list(p.local_gains.stiffness),
                            "damping": list(p.local_gains.damping)},
            "environment": environment, "torque_limit": p.torque_limit}


@dataclass(frozen=True)
class Setup:
    """A teleoperation setup: the plant, the network, the operator and the start.

    Build it with :meth:`paper`, :meth:`from_file`, :meth:`from_data` or :meth:`from_params`;
    every entry point of the toolkit takes one (``setup=``) and draws its scenarios with
    :meth:`scenarios`.

    Parameters
    ----------
    params : TeleoperatorParams
        The model: arms, joints, local gains, operator spring and damper, environment, torque
        limit (its operator sines and initial state are those of ``operator`` and ``start``
        where they are fixed).
    network : Network
        Delay range and profiles of each direction.
    operator : OperatorSetup
        Operator spring, damper and motions.
    start : StartSpec or StartMix
        Initial positions (one start, or several drawn per scenario).
    base : Path, optional
        Directory of the file it was read from (relative ``csv:`` paths start there); not
        part of the setup's identity.
    other_plants : tuple of TeleoperatorParams, optional
        Further plants the scenarios run (each scenario draws one of :attr:`plants`
        uniformly); none by default.
    plant_ranges : tuple of PlantRange, optional
        The ranges of each plant of :attr:`plants` (its values there are the midpoints): each
        scenario draws its plant's ranged values uniformly. Empty when no plant has one.

    Examples
    --------
    >>> setup = Setup.paper()
    >>> setup.n_joints, setup.network.bounds
    (2, (1.0, 1.0))
    >>> setup.scenarios(0, batch=4).batch
    4
    """

    params: TeleoperatorParams = field(default_factory=TeleoperatorParams)
    network: Network = field(default_factory=Network)
    operator: OperatorSetup = field(default_factory=OperatorSetup)
    start: StartSpec | StartMix = field(default_factory=lambda: StartSpec.fixed(_PAPER.initial))
    base: Path | None = field(default=None, compare=False)
    other_plants: tuple[TeleoperatorParams, ...] = ()
    plant_ranges: tuple[PlantRange, ...] = ()

    def __post_init__(self) -> None:
        n = self.params.n_joints
        if self.start.n_joints != n:
            raise SetupError(f"start: has {self.start.n_joints} joints, the arm has {n}")
        object.__setattr__(self, "other_plants", tuple(self.other_plants))
        for k, plant in enumerate(self.other_plants, start=1):
            if plant.n_joints != n:
                raise SetupError(f"plant[{k}]: has {plant.n_joints} joints, the first plant {n}")
        ranges = tuple(self.plant_ranges) if any(self.plant_ranges) else ()
        if ranges and len(ranges) != len(self.plants):
            raise SetupError(f"plant_ranges: {len(ranges)} ranges for {len(self.plants)} plants")
        for k, (plant, interval) in enumerate(zip(self.plants, ranges, strict=True)
                                              if ranges else ()):
            if any(len(low) != n for low, _ in interval.bounds.values()):
                raise SetupError(f"plant[{k}]: a range needs {n} values per entry")
            if interval.nominal(plant) != plant:
                raise SetupError(f"plant[{k}]: its ranged values must be their midpoints")
        object.__setattr__(self, "plant_ranges", ranges)

    @property
    def ranges(self) -> tuple[PlantRange, ...]:
        """The range of each plant of :attr:`plants` (empty ranges where none)."""
        return self.plant_ranges or (PlantRange(),) * len(self.plants)

    @property
    def plants(self) -> tuple[TeleoperatorParams, ...]:
        """Every plant the scenarios run: ``params``, then :attr:`other_plants`."""
        return (self.params, *self.other_plants)

    @classmethod
    def paper(cls) -> Setup:
        """The paper's setup (identical to the shipped ``paper_setup.yaml``)."""
        return cls()

    @classmethod
    def from_params(cls, params: TeleoperatorParams, network: Network | None = None) -> Setup:
        """A setup of a model: its operator's sines with the paper's gains, its fixed start.

        Parameters
        ----------
        params : TeleoperatorParams
            The model.
        network : Network, optional
            The network; the paper's by default.

        Returns
        -------
        Setup
            Scenarios drawn from it equal :func:`~teleopkit.sim.scenarios.paper_scenarios` of
            ``params`` when the network is the paper's.
        """
        if not isinstance(params, TeleoperatorParams):
            raise TypeError(f"params must be a TeleoperatorParams, got {type(params).__name__}")
        operator = OperatorSetup(params.operator.stiffness, params.operator.damping,
                                 MotionSpec.paper(params.operator))
        return cls(params, network or Network(), operator, StartSpec.fixed(params.initial))

    @classmethod
    def from_data(cls, data: Any, base: str | Path | None = None) -> Setup:
        """Read a setup from parsed YAML data.

        Parameters
        ----------
        data : mapping
            The document (keys ``plant``, ``network``, ``operator``, ``start``).
        base : str or Path, optional
            Directory that relative ``csv:`` paths start from (the current one by default).

        Returns
        -------
        Setup
            The setup.

        Raises
        ------
        SetupError
            One line naming the key path and the problem.
        """
        root = Path(base) if base is not None else Path.cwd()
        entries = Node(data).fields(("plant", "network", "operator", "start"), ("plant",))
        node = entries["plant"]
        variants, ranges = zip(*(_plant(item) for item in (
            node.items() if isinstance(node.value, list) else (node,))), strict=True)
        n = variants[0]["local_arm"].n_joints
        for k, parts in enumerate(variants):
            if parts["local_arm"].n_joints != n:
                raise SetupError(f"plant[{k}]: has {parts['local_arm'].n_joints} joints, the "
                                 f"first plant {n}")
        network = entries["network"].fields(("forward", "backward")) if "network" in entries \
            else {}
        channels = [Channel.from_node(network[key], root, k) if key in network else Channel()
                    for k, key in enumerate(("forward", "backward"))]
        operator = OperatorSetup.from_node(entries.get("operator", Node(None, "operator")), n,
                                           root)
        start = StartMix.from_node(entries.get("start", Node("paper" if n == 2 else "rest",
                                                             "start")), n)
        try:
            plants = tuple(TeleoperatorParams(
                **parts, remote_gains=PDGains.uniform(10.0, 30.0, n),
                operator=operator.model(n), initial=start.initial()) for parts in variants)
        except ValueError as error:
            raise SetupError(f"plant: {error}") from None
        return cls(plants[0], Network(*channels), operator, start, root, plants[1:], ranges)

    @classmethod
    def from_file(cls, path: str | Path) -> Setup:
        """Read a setup file (YAML or JSON); relative ``csv:`` paths start at its directory.

        Parameters
        ----------
        path : str or Path
            The file.

        Returns
        -------
        Setup
            The setup.

        Raises
        ------
        SetupError
            One line naming the file, the key path and the problem.
        """
        path = Path(path)
        data = load_document(path)
        try:
            return cls.from_data(data, path.resolve().parent)
        except SetupError as error:
            raise SetupError(f"{path}: {error}") from None

    def to_data(self, base: str | Path | None = None) -> dict[str, Any]:
        """The setup as setup-file data (every key written out).

        Parameters
        ----------
        base : str or Path, optional
            Directory the ``csv:`` paths are written relative to (absolute by default).

        Returns
        -------
        dict
            Keys ``plant``, ``network``, ``operator``, ``start``.
        """
        root = Path(base) if base is not None else None
        plants = [_plant_data(params, ranges) for params, ranges in zip(self.plants, self.ranges,
                                                                        strict=True)]
        return {
            "plant": plants[0] if len(plants) == 1 else plants,
            "network": {"forward": self.network.forward.to_data(root),
                        "backward": self.network.backward.to_data(root)},
            "operator": {"stiffness": self.operator.stiffness,
                         "damping": self.operator.damping,
                         "motion": self.operator.motion.to_data(root)},
            "start": self.start.to_data(),
        }

    def to_yaml(self, base: str | Path | None = None) -> str:
        """The setup as the text of a setup file.

        Parameters
        ----------
        base : str or Path, optional
            As for :meth:`to_data`.

        Returns
        -------
        str
            YAML.
        """
        import yaml

        return yaml.safe_dump(self.to_data(base), sort_keys=False, default_flow_style=None)

    def to_file(self, path: str | Path) -> None:
        """Write the setup file (``csv:`` paths relative to its directory where they can be).

        Parameters
        ----------
        path : str or Path
            The file (YAML).
        """
        from teleopkit.files import atomic_write

        path = Path(path)
        text = self.to_yaml(path.resolve().parent)
        atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))

    @property
    def record(self) -> dict[str, Any]:
        """The setup as JSON-ready data with absolute paths and the digests of its data files."""
        digests = (self.network.forward.digests() + self.network.backward.digests()
                   + self.operator.motion.digests())
        return {**json_ready(self.to_data()), "data_files": digests}

    @property
    def fingerprint(self) -> str:
        """SHA-256 of :attr:`record` (16 hex digits): what comparators are cached by."""
        text = json.dumps(self.record, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def n_joints(self) -> int:
        """Joints of each arm."""
        return self.params.n_joints

    def with_delay(self, spec: str) -> Setup:
        """A copy with both directions' delays drawn from one spec instead.

        Parameters
        ----------
        spec : str
            A delay spec (:func:`~teleopkit.delays.spec.parse_delay`), for example a shape a
            tuner never saw in training.

        Returns
        -------
        Setup
            The same plant, operator and start; each channel's range is what the spec reaches.
        """
        reaches = [spec_reach(spec, direction) for direction in (0, 1)]
        return replace(self, network=Network(*(Channel(low, high, (spec,))
                                               for low, high in reaches)))

    def scenarios(self, rng: np.random.Generator | int = 0, batch: int = 1,
                  delay: str | float | tuple[DelayProfile, DelayProfile] | None = None,
                  ) -> Scenario:
        """Draw ``batch`` scenarios: operator motions, then delays, starts and plants.

        A plant with ranges gives each of its scenarios a plant of its own, drawn last.

        Parameters
        ----------
        rng : numpy.random.Generator or int
            Generator or seed (a non-negative integer).
        batch : int
            Scenarios.
        delay : str, float or (DelayProfile, DelayProfile), optional
            Delays in place of the network's (:func:`~teleopkit.delays.spec.delay_pair`): a
            spec, a constant in seconds or the two profiles.

        Returns
        -------
        Scenario
            The batch (for the paper's setup, the draws of
            :func:`~teleopkit.sim.scenarios.paper_scenarios`).
        """
        from teleopkit.delays.spec import delay_pair
        from teleopkit.sim.scenarios import Scenario, generator

        if isinstance(batch, bool) or not isinstance(batch, int | np.integer) or batch < 1:
            raise ValueError(f"batch must be a whole number of scenarios >= 1, got {batch!r}")
        rng = generator(rng)
        gains, motion = self.operator.motion.draw(rng, batch, self.n_joints)
        forward, backward = (self.network.draw(rng, batch) if delay is None
                             else delay_pair(delay, rng))
        start = self.start.draw(rng, batch)
        index = rng.integers(len(self.plants), size=batch) if len(self.plants) > 1 else None
        if not self.plant_ranges:
            return Scenario(self.params, forward, backward, gains, motion, start,
                            self.other_plants, index)
        drawn = [self.plant_ranges[k].draw(self.plants[k], rng, 1)[0]
                 for k in (np.zeros(batch, dtype=int) if index is None else index)]
        return Scenario(drawn[0], forward, backward, gains, motion, start, tuple(drawn[1:]),
                        np.arange(batch))

    def describe(self) -> list[str]:
        """What the setup describes, a line per part, for people."""
        plants = _describe_plants(self.plants, self.ranges)
        channels = [f"{name} delay: {ch.min:g}-{ch.max:g} s, profile {', '.join(ch.profiles)}"
                    for name, ch in (("forward", self.network.forward),
                                     ("backward", self.network.backward))]
        return [*plants, *channels,
                f"operator: K_s {self.operator.stiffness:g}, K_d {self.operator.damping:g}; "
                f"{self.operator.motion.describe()}",
                f"start: {self.start.describe()}",
                f"setup fingerprint {self.fingerprint} (plant, network, operator and start)"]


def _describe_plants(plants: tuple[TeleoperatorParams, ...],
                     ranges: tuple[PlantRange, ...]) -> list[str]:
    """The first plant whole, each other one by the lines where it differs from the first."""
    first = _describe_plant(plants[0], ranges[0])
    if len(plants) == 1:
        return first
    lines = [f"plant 1 of {len(plants)}, {line}" for line in first]
    for k, (params, interval) in enumerate(zip(plants[1:], ranges[1:], strict=True), start=2):
        differs = [line for line in _describe_plant(params, interval) if line not in first]
        lines += [f"plant {k} of {len(plants)}, {line}" for line in differs or
                  ["the same as plant 1"]]
    return lines


def _describe_plant(p: TeleoperatorParams, ranges: PlantRange) -> list[str]:
    """A plant for people: its arms, joints, local gains, environment and ranges."""
    links = "link" if p.n_joints == 1 else "links"
    arms = [f"{name} arm: {p.n_joints} {links}, lengths {listed(arm.lengths)} m, masses "
            f"{listed(arm.masses)} kg{_describe_links(arm)}"
            for name, arm in (("local", p.local_arm), ("remote", p.remote_arm))]
    wall = ("free space" if not isinstance(p.environment, Wall)
            else f"a wall at {listed(p.environment.position)} rad")
    return [*arms,
            f"elastic joints: stiffness {listed(p.joints.stiffness)} N m/rad, rotor inertia "
            f"{listed(p.joints.rotor_inertia)} kg m^2",
            f"local gains: K_l {listed(p.local_gains.stiffness)}, B_l "
            f"{listed(p.local_gains.damping)}; {wall}; torque limit {p.torque_limit:g} N m",
            *(f"{PLANT_LABELS[name]} drawn per scenario in {listed(low)} to {listed(high)} "
              f"(nominal: the midpoints)" for name, (low, high) in ranges.bounds.items())]


def _describe_links(arm: PlanarArm) -> str:
    """An arm's centres of mass and link inertias where they are not the point-mass default."""
    return ((f", centres of mass {listed(arm.com)} m" if arm.com is not None else "")
            + (f", link inertias {listed(arm.inertia)} kg m^2" if arm.inertia is not None
               else "")
            + (" (point masses at the link tips)" if arm.com is None and arm.inertia is None
               else ""))


SHIPPED_SETUPS: Mapping[str, str] = MappingProxyType({"paper": PAPER_SETUP_FILE,
                                                       "mixed": "mixed_setup.yaml"})
"""Setup files shipped in ``teleopkit/data``, by the name ``--setup`` takes in place of a file:
``paper`` the paper's setup, ``mixed`` a training distribution around it (decaying and lasting
sine operators, random smooth motions, a still operator; the paper's starts, at rest, aligned
and random ones; the paper's, sinusoidal and constant delays)."""


def paper_setup_path() -> Path:
    """Path of the shipped paper setup file."""
    return shipped_setup_path("paper")


def shipped_setup_path(name: str) -> Path:
    """Path of a shipped setup file.

    Parameters
    ----------
    name : str
        A name of :data:`SHIPPED_SETUPS`.

    Returns
    -------
    Path
        The file.

    Raises
    ------
    ValueError
        If there is no shipped setup of that name (one line listing the names).
    """
    if name not in SHIPPED_SETUPS:
        raise ValueError(f"no shipped setup {name!r} (shipped: {', '.join(SHIPPED_SETUPS)})")
    return Path(str(resources.files("teleopkit") / "data" / SHIPPED_SETUPS[name]))
