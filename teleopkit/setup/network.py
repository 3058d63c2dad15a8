"""The network of a setup: one delay channel per direction, its bounds and its profiles.

Each direction has a declared range ``[min, max]`` (what certificates must cover: the delay
floor and bound) and one or more delay specs (:func:`teleopkit.delays.parse_delay`); with
several, each scenario of a batch draws one of them at random. Every profile must stay inside
the range. The delay modules load when a profile is drawn or checked, so that a command that
only reads a setup's plant (the closed form's answer) loads no compiled code.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from teleopkit.setup.reading import Node, SetupError, read_once

if TYPE_CHECKING:
    from teleopkit.delays.profiles import DelayProfile

__all__ = ["Channel", "Network", "file_digest", "spec_reach"]

_SLACK = 1e-9
"""Seconds by which a profile may pass its channel's range (rounding of its declared bounds)."""


def file_digest(path: str | Path) -> str:
    """SHA-256 of a file's bytes, 16 hex digits (what a fingerprint records of a data file).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    str
        The digest.
    """
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def _resolve(spec: str, base: Path | None) -> str:
    """``csv:PATH`` with ``PATH`` made absolute relative to ``base``; other specs unchanged."""
    kind, _, rest = spec.partition(":")
    if kind != "csv" or not rest or base is None or Path(rest).is_absolute():
        return spec
    return f"csv:{(base / rest).resolve()}"


def _relative(spec: str, base: Path | None) -> str:
    """The inverse of :func:`_resolve` where the file lies under ``base``."""
    kind, _, rest = spec.partition(":")
    if kind != "csv" or base is None:
        return spec
    try:
        return f"csv:{Path(rest).relative_to(base.resolve())}"
    except ValueError:
        return spec


def spec_reach(spec: str, direction: int) -> tuple[float, float]:
    """Declared floor and bound of the profiles a delay spec draws (the paper's: scales 0.5-1).

    Parameters
    ----------
    spec : str
        A delay spec.
    direction : int
        0 forward, 1 backward.

    Returns
    -------
    (float, float)
        Floor and bound in seconds.
    """
    from teleopkit.delays.profiles import FourierDelay, delay_floor

    if spec == "paper":
        return FourierDelay(0.5).floor, FourierDelay(1.0).bound
    profile = _parsed(spec, np.random.default_rng(0))[direction]
    return delay_floor(profile), float(profile.bound)


@dataclass(frozen=True)
class Channel:
    """One direction of the network.

    Parameters
    ----------
    min : float
        Smallest delay in seconds (the floor certificates may assume).
    max : float
        Largest delay in seconds (the bound certificates must cover).
    profiles : tuple of str
        Delay specs (``paper``, ``constant:T``, ``sine:MEAN:AMP:FREQ``,
        ``switching:LOW:HIGH:DWELL``, ``csv:PATH``); each scenario draws one.
    """

    min: float = 0.0
    max: float = 1.0
    profiles: tuple[str, ...] = ("paper",)

    def __post_init__(self) -> None:
        if not (0 <= self.min <= self.max < np.inf):
            raise SetupError(f"delay range [{self.min:g}, {self.max:g}] needs 0 <= min <= max "
                             "< inf")
        if not self.profiles:
            raise SetupError("a delay channel needs at least one profile")

    @classmethod
    def from_node(cls, node: Node, base: Path | None, direction: int) -> Channel:
        """Read ``{min, max, profile}`` and check every profile against the range.

        Parameters
        ----------
        node : Node
            The channel's entry (``network.forward`` or ``network.backward``).
        base : Path, optional
            Directory that relative ``csv:`` paths start from.
        direction : int
            0 forward (local to remote), 1 backward.

        Returns
        -------
        Channel
            The channel.
        """
        entries = node.fields(("min", "max", "profile"), ("max",))
        low = entries["min"].number(0.0) if "min" in entries else 0.0
        high = entries["max"].number(0.0)
        if low > high:
            raise entries["min"].error(f"min {low:g} s is above max {high:g} s")
        profile = entries.get("profile", Node("paper", f"{node.path}.profile"))
        specs = (profile.items() if isinstance(profile.value, list) else iter([profile]))
        nodes = list(specs)
        channel = cls(low, high, tuple(_resolve(item.text(), base) for item in nodes))
        for item, spec in zip(nodes, channel.profiles, strict=True):
            channel._check(item, spec, direction)
        return channel

    def _check(self, node: Node, spec: str, direction: int) -> None:
        """Refuse a spec that does not parse or leaves ``[min, max]``, naming its key path."""
        try:
            floor, bound = spec_reach(spec, direction)
        except (ValueError, OSError) as error:
            raise node.error(str(error).splitlines()[0]) from None
        if bound > self.max + _SLACK or floor < self.min - _SLACK:
            raise node.error(f"{spec} reaches delays in [{floor:.4g}, {bound:.4g}] s, outside "
                             f"the channel's range [{self.min:g}, {self.max:g}] s")

    def reach(self, direction: int) -> tuple[float, float]:
        """The smallest and largest delays its profiles can take, within ``[min, max]``.

        This is what a certificate must cover for the scenarios drawn from the channel (for the
        paper's profile about 0.451-1 s).

        Parameters
        ----------
        direction : int
            0 forward, 1 backward.

        Returns
        -------
        (float, float)
            Floor and bound in seconds.
        """
        reaches = [spec_reach(spec, direction) for spec in self.profiles]
        return (float(max(self.min, min(low for low, _ in reaches))),
                float(min(self.max, max(high for _, high in reaches))))

    def to_data(self, base: Path | None) -> dict[str, Any]:
        """The channel as setup-file data.

        Parameters
        ----------
        base : Path, optional
            Directory the ``csv:`` paths are written relative to where possible.

        Returns
        -------
        dict
            ``min``, ``max`` and ``profile`` (one spec or a list).
        """
        specs = [_relative(spec, base) for spec in self.profiles]
        return {"min": self.min, "max": self.max,
                "profile": specs[0] if len(specs) == 1 else specs}

    def digests(self) -> list[str]:
        """SHA-256 of each ``csv:`` trace (a fingerprint covers the data, not its path)."""
        return [file_digest(spec.partition(":")[2]) for spec in self.profiles
                if spec.startswith("csv:")]

    def draw(self, rng: np.random.Generator, batch: int, direction: int) -> DelayProfile:
        """Delay profiles of ``batch`` scenarios.

        With one spec, ``paper`` draws a scale ``U[0.5, 1]`` per scenario (the paper's
        randomisation) and other specs give one profile for the batch; with several, each
        scenario draws a spec uniformly and the profiles are stacked.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws.
        batch : int
            Scenarios.
        direction : int
            0 forward, 1 backward (specs such as ``sine`` differ by direction).

        Returns
        -------
        DelayProfile
            One column, or one per scenario.
        """
        from teleopkit.delays.combinators import StackedDelay

        if len(self.profiles) == 1:
            return self._profile(self.profiles[0], rng, batch, direction)
        choice = rng.integers(len(self.profiles), size=batch)
        used = [k for k in range(len(self.profiles)) if np.any(choice == k)]
        parts = tuple(self._profile(self.profiles[k], rng, int(np.sum(choice == k)), direction,
                                    per_scenario=True) for k in used)
        columns = np.concatenate([np.flatnonzero(choice == k) for k in used])
        return StackedDelay(parts, tuple(int(i) for i in np.argsort(columns)))

    @staticmethod
    def _profile(spec: str, rng: np.random.Generator, batch: int, direction: int,
                 per_scenario: bool = False) -> DelayProfile:
        """One spec's profile for ``batch`` scenarios (``per_scenario``: ``batch`` columns)."""
        from teleopkit.delays.combinators import StackedDelay
        from teleopkit.delays.profiles import FourierDelay

        if spec == "paper":
            return FourierDelay(rng.uniform(0.5, 1.0, size=batch))
        profile = _parsed(spec, rng)[direction]
        width = np.shape(profile.sample(np.zeros(1)))[-1]
        if per_scenario and width != batch:
            return StackedDelay((profile,) * batch)
        return profile


@dataclass(frozen=True)
class Network:
    """Both directions of the network.

    Parameters
    ----------
    forward : Channel
        Local to remote: the delay ``T_l(t)`` of the local positions the remote receives.
    backward : Channel
        Remote to local: the delay ``T_r(t)`` of the motor positions the local receives.
    """

    forward: Channel = field(default_factory=Channel)
    backward: Channel = field(default_factory=Channel)

    @property
    def bounds(self) -> tuple[float, float]:
        """``(T_l*, T_r*)``: the largest delays a certificate must cover."""
        return self.forward.max, self.backward.max

    @property
    def floors(self) -> tuple[float, float]:
        """The smallest delays of each direction."""
        return self.forward.min, self.backward.min

    @property
    def reached_bounds(self) -> tuple[float, float]:
        """``(T_l*, T_r*)`` the drawn delays can reach (:meth:`Channel.reach`)."""
        return self.forward.reach(0)[1], self.backward.reach(1)[1]

    @property
    def reached_floors(self) -> tuple[float, float]:
        """The smallest delays the drawn profiles can take in each direction."""
        return self.forward.reach(0)[0], self.backward.reach(1)[0]

    def draw(self, rng: np.random.Generator, batch: int) -> tuple[DelayProfile, DelayProfile]:
        """Forward then backward profiles of ``batch`` scenarios (:meth:`Channel.draw`).

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws.
        batch : int
            Scenarios.

        Returns
        -------
        tuple of DelayProfile
            Forward and backward profiles.
        """
        return self.forward.draw(rng, batch, 0), self.backward.draw(rng, batch, 1)

    def check_ends(self, duration: float) -> None:
        """Refuse a recorded delay trace (``csv:PATH``) that ends before a run does.

        Parameters
        ----------
        duration : float
            Length of the run in seconds.

        Raises
        ------
        ValueError
            As :func:`~teleopkit.delays.spec.check_trace_ends` (other profiles never end).
        """
        from teleopkit.delays.spec import check_trace_ends

        specs = dict.fromkeys(self.forward.profiles + self.backward.profiles)
        for spec in (s for s in specs if s.startswith("csv:")):
            check_trace_ends(_parsed(spec), duration)


def _parsed(spec: str, rng: np.random.Generator | None = None
            ) -> tuple[DelayProfile, DelayProfile]:
    """:func:`~teleopkit.delays.spec.parse_delay`, a recorded trace read once.

    While its file stays unchanged (:func:`~teleopkit.setup.reading.read_once`), the bounds,
    the checks and every batch's draw share one reading.
    """
    from teleopkit.delays.profiles import TraceDelay
    from teleopkit.delays.spec import parse_delay

    if spec.startswith("csv:"):
        trace = read_once(TraceDelay.from_csv, spec.removeprefix("csv:"))
        return trace, trace
    return parse_delay(spec, rng)
