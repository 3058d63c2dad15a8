"""The operator of a setup: its spring and damper, and the motions it makes.

Motions (the ``operator.motion`` key of a setup file):

- ``paper``: the paper's decaying sines, each joint's scaled per scenario by a gain drawn from
  ``[-1, -0.5] U [0.5, 1]``;
- ``{sines: {amplitudes, frequencies, phases, decays, gains}}``: one sine per joint (amplitude in
  rad, angular frequency in rad/s, phase in rad, decay rate in 1/s, zero for a motion that
  never dies out), scaled per scenario by a gain whose magnitude is drawn from ``gains``
  (``[low, high]``, default ``[0.5, 1]``) with a random sign;
- ``{smooth: {amplitude, frequency, decay, components}}``: random smooth motions, a few sines per
  joint with peak angle, frequencies (Hz) and decay rates drawn from the given ranges
  (:func:`~teleopkit.sim.motions.smooth_motions`);
- ``csv:PATH``: a recorded motion, columns ``t, q1..qn`` in radians (relative to the setup file),
  from ``t = 0`` to at least the end of every run it drives (a shorter one is refused, as a
  delay trace is);
- ``still``: the operator holds the arm at the origin;
- a list of these (but recorded motions): each scenario draws one of them uniformly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from teleopkit.model.params import Operator
from teleopkit.setup.network import file_digest
from teleopkit.setup.reading import Node, listed, read_once
from teleopkit.sim.motions import (
    Motion,
    RecordedMotion,
    SineMotion,
    check_motion_ends,
    smooth_motions,
)

__all__ = ["MotionSpec", "OperatorSetup"]

_SINE_KEYS = ("amplitudes", "frequencies", "phases", "decays")
_PAPER_GAINS = (0.5, 1.0)


@dataclass(frozen=True)
class MotionSpec:
    """What the operator does in each scenario.

    Parameters
    ----------
    kind : {"sines", "smooth", "csv", "still", "mix"}
        The family (``paper`` is ``sines`` with the paper's values).
    values : tuple of (str, object) pairs
        Its settings: for ``sines`` the four per-joint tuples and ``gains``; for ``smooth`` the
        ranges ``amplitude``, ``frequency``, ``decay`` and ``components``; for ``csv`` the
        absolute ``path``; for ``mix`` the ``parts`` (motions, each scenario draws one).
    """

    kind: str
    values: tuple[tuple[str, Any], ...] = ()

    @property
    def settings(self) -> dict[str, Any]:
        """The settings as a dictionary."""
        return dict(self.values)

    @classmethod
    def paper(cls, operator: Operator | None = None) -> MotionSpec:
        """The paper's motion: ``operator``'s sines, gains ``0.5-1`` with a random sign.

        Parameters
        ----------
        operator : Operator, optional
            Whose sines; the paper's by default.

        Returns
        -------
        MotionSpec
            A ``sines`` motion.
        """
        operator = operator if operator is not None else Operator()
        sines = tuple((key, getattr(operator, key)) for key in _SINE_KEYS)
        return cls("sines", (*sines, ("gains", _PAPER_GAINS)))

    @classmethod
    def from_node(cls, node: Node, n: int, base: Path | None) -> MotionSpec:
        """Read an ``operator.motion`` entry (a list: a mix of motions).

        Parameters
        ----------
        node : Node
            The entry.
        n : int
            Joints of the arm.
        base : Path, optional
            Directory that a relative ``csv:`` path starts from.

        Returns
        -------
        MotionSpec
            The motion.
        """
        if isinstance(node.value, list):
            parts = tuple(cls.from_node(item, n, base) for item in node.items())
            if any(part.kind in ("csv", "mix") for part in parts):
                raise node.error("a list of motions takes paper, still, sines and smooth")
            return parts[0] if len(parts) == 1 else cls("mix", (("parts", parts),))
        if isinstance(node.value, str):
            word, _, rest = node.text().partition(":")
            if word == "paper" and not rest:
                if n != 2:
                    raise node.error(f"the paper's motion moves 2 joints, the arm has {n}: give "
                                     "sines, smooth, csv:PATH or still")
                return cls.paper()
            if word == "still" and not rest:
                return cls("still")
            if word == "csv" and rest:
                return cls._recorded(node, Path(rest) if base is None else base / rest, n)
            raise node.error(f"unknown motion {node.value!r}; use paper, still, csv:PATH, "
                             "{sines: ...} or {smooth: ...}")
        entries = node.fields(("sines", "smooth"))
        if len(entries) != 1:
            raise node.error("give one of sines or smooth")
        if "sines" in entries:
            fields = entries["sines"].fields((*_SINE_KEYS, "gains"), ("amplitudes",))
            values = [(key, fields[key].numbers(n, 0.0 if key != "phases" else -np.inf)
                       if key in fields else (0.0,) * n) for key in _SINE_KEYS]
            gains = fields["gains"].interval(0.0) if "gains" in fields else _PAPER_GAINS
            return cls("sines", (*values, ("gains", gains)))
        fields = entries["smooth"].fields(("amplitude", "frequency", "decay", "components"),
                                          ("amplitude", "frequency"))
        components = fields["components"].number(1.0) if "components" in fields else 3.0
        if components != int(components):
            raise fields["components"].error(f"must be a whole number, got {components:g}")
        return cls("smooth", (
            ("amplitude", fields["amplitude"].interval(0.0)),
            ("frequency", fields["frequency"].interval(0.0)),
            ("decay", fields["decay"].interval(0.0) if "decay" in fields else (0.0, 0.0)),
            ("components", int(components))))

    @classmethod
    def _recorded(cls, node: Node, path: Path, n: int) -> MotionSpec:
        try:
            motion = _recording(path)
        except ValueError as error:
            raise node.error(str(error)) from None
        if motion.n_joints != n:
            raise node.error(f"{path} has {motion.n_joints} joint column(s), the arm has {n} "
                             "joints")
        return cls("csv", (("path", str(path.resolve())),))

    def to_data(self, base: Path | None) -> Any:
        """The motion as setup-file data.

        Parameters
        ----------
        base : Path, optional
            Directory a recorded motion's path is written relative to where possible.

        Returns
        -------
        str or dict
            A name, ``csv:PATH`` or a mapping.
        """
        if self == MotionSpec.paper():
            return "paper"
        if self.kind == "still":
            return "still"
        settings = self.settings
        if self.kind == "mix":
            return [part.to_data(base) for part in settings["parts"]]
        if self.kind == "csv":
            path = Path(settings["path"])
            try:
                path = path.relative_to(base.resolve()) if base is not None else path
            except ValueError:
                pass
            return f"csv:{path}"
        return {self.kind: {key: list(value) if isinstance(value, tuple) else value
                            for key, value in settings.items()}}

    def check_ends(self, duration: float) -> None:
        """Refuse a recorded motion that ends before a run of ``duration`` seconds does.

        Parameters
        ----------
        duration : float
            Length of the run in seconds.

        Raises
        ------
        ValueError
            As :func:`~teleopkit.sim.motions.check_motion_ends` (other motions never end).
        """
        if self.kind == "csv":
            check_motion_ends(_recording(self.settings["path"]), duration)

    def digests(self) -> list[str]:
        """SHA-256 of a recorded motion's file (a fingerprint covers the data)."""
        return [file_digest(self.settings["path"])] if self.kind == "csv" else []

    def draw(self, rng: np.random.Generator, batch: int, n: int) -> tuple[np.ndarray, Motion]:
        """Reference gains ``(batch, n)`` and the motion of ``batch`` scenarios.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws (``sines``: the gains; ``smooth``: the motions).
        batch : int
            Scenarios.
        n : int
            Joints.

        Returns
        -------
        gains : ndarray, shape (batch, n)
            Per-scenario gains on the motion.
        motion : Motion
            One shared column (``sines``, ``csv``, ``still``) or one per scenario.
        """
        settings = self.settings
        ones = np.ones((batch, n))
        if self.kind == "mix":
            return _draw_mix(settings["parts"], rng, batch, n)
        if self.kind == "sines":
            low, high = settings["gains"]
            magnitude = rng.uniform(low, high, size=(batch, n))
            gains = np.where(rng.random((batch, n)) < 0.5, -magnitude, magnitude)
            sines = Operator(amplitudes=settings["amplitudes"],
                             frequencies=settings["frequencies"], phases=settings["phases"],
                             decays=settings["decays"])
            return gains, SineMotion.from_operator(sines)
        if self.kind == "smooth":
            return ones, smooth_motions(rng, batch, n, settings["amplitude"],
                                        settings["frequency"], settings["decay"],
                                        settings["components"])
        if self.kind == "csv":
            return ones, _recording(settings["path"])
        zeros = np.zeros((1, 1, n))
        return ones, SineMotion(zeros, zeros, zeros, zeros)

    def describe(self) -> str:
        """One line for people."""
        settings = self.settings
        if self == MotionSpec.paper():
            return "the paper's decaying sines, gains +-0.5-1 per scenario"
        if self.kind == "sines":
            decays = settings["decays"]
            kind = "decaying" if any(decays) else "non-decaying"
            low, high = settings["gains"]
            return (f"{kind} sines, amplitudes {listed(settings['amplitudes'])} rad, gains "
                    f"+-{low:g}-{high:g} per scenario")
        if self.kind == "smooth":
            low, high = settings["amplitude"]
            f_low, f_high = settings["frequency"]
            return (f"random smooth motions, peak {low:g}-{high:g} rad, {settings['components']}"
                    f" sines per joint at {f_low:g}-{f_high:g} Hz")
        if self.kind == "csv":
            return f"the recorded motion {settings['path']}"
        if self.kind == "mix":
            return "one of: " + "; ".join(part.describe() for part in settings["parts"])
        return "the operator holds the origin"


def _recording(path: str | Path) -> RecordedMotion:
    """The recorded motion in ``path``, read once while the file stays as it is."""
    return read_once(RecordedMotion.from_csv, path)


def _draw_mix(parts: tuple[MotionSpec, ...], rng: np.random.Generator, batch: int, n: int,
              ) -> tuple[np.ndarray, SineMotion]:
    """Each scenario draws one of ``parts`` (all sums of sines): gains and one column each."""
    choice = rng.integers(len(parts), size=batch)
    gains = np.ones((batch, n))
    drawn: list[tuple[np.ndarray, SineMotion]] = []
    for k, part in enumerate(parts):
        rows = np.flatnonzero(choice == k)
        if rows.size:
            part_gains, motion = part.draw(rng, int(rows.size), n)
            gains[rows] = part_gains
            drawn.append((rows, motion))  # type: ignore[arg-type]
    components = max(motion.amplitudes.shape[1] for _, motion in drawn)
    arrays = {name: np.zeros((batch, components, n)) for name in _ARRAYS}
    for rows, motion in drawn:
        for name in _ARRAYS:
            values = np.broadcast_to(getattr(motion, name), motion.amplitudes.shape)
            width = values.shape[1]
            arrays[name][rows, :width] = values  # one column broadcasts to every row
    return gains, SineMotion(*(arrays[name] for name in _ARRAYS))


_ARRAYS = ("amplitudes", "frequencies", "phases", "decays")


@dataclass(frozen=True)
class OperatorSetup:
    """The operator: a spring-damper to a reference motion.

    Parameters
    ----------
    stiffness : float
        ``K_s`` in N m / rad.
    damping : float
        ``K_d`` in N m s / rad.
    motion : MotionSpec
        What it does in each scenario.
    """

    stiffness: float = 10.0
    damping: float = 2.0
    motion: MotionSpec = field(default_factory=MotionSpec.paper)

    @classmethod
    def from_node(cls, node: Node, n: int, base: Path | None) -> OperatorSetup:
        """Read the ``operator`` entry.

        Parameters
        ----------
        node : Node
            The entry (its value None: the defaults).
        n : int
            Joints of the arm.
        base : Path, optional
            Directory that a relative ``csv:`` path starts from.

        Returns
        -------
        OperatorSetup
            The operator.
        """
        entries = node.fields(("stiffness", "damping", "motion"))
        motion = (MotionSpec.from_node(entries["motion"], n, base) if "motion" in entries
                  else MotionSpec.paper() if n == 2 else MotionSpec("still"))
        return cls(entries["stiffness"].number(0.0) if "stiffness" in entries else 10.0,
                   entries["damping"].number(0.0) if "damping" in entries else 2.0, motion)

    def model(self, n: int) -> Operator:
        """The operator of the model: its sines, or none (zero amplitudes).

        A scenario drawn from the setup carries the motion itself; these sines are what a run
        built from the model alone follows.

        Parameters
        ----------
        n : int
            Joints of the arm.

        Returns
        -------
        Operator
            Spring, damper and sines.
        """
        if self.motion.kind == "sines":
            settings = self.motion.settings
            return Operator(self.stiffness, self.damping, *(settings[key] for key in _SINE_KEYS))
        zeros = (0.0,) * n
        return Operator(self.stiffness, self.damping, zeros, zeros, zeros, zeros)
