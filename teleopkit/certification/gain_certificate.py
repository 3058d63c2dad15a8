"""The gain certificate: a verdict on a box of remote gains, as an object and as JSON.

A certificate is a value: it names what it certifies (the plant, with a fingerprint, from
:func:`~teleopkit.model.records.plant_record`; the delay bounds; the gain class; the box) and
what it claims. :meth:`GainCertificate.check` refuses it, in one line, for another plant or for
delays that can exceed its bounds. Whether the claim holds is re-checked above it, by
:mod:`teleopkit.certification.verification`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.nuno.guarantee import Start, StorageGuarantee, storage_guarantee
from teleopkit.certification.nuno.lyapunov import ScheduledStorage
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.model.params import InitialState, TeleoperatorParams
from teleopkit.model.plant_range import PlantRange
from teleopkit.model.records import plant_params
from teleopkit.setup.start import StartMix, StartSpec

__all__ = ["DelayBoundError", "GainCertificate"]


class DelayBoundError(ValueError):
    """Delays that can exceed a certificate's bound (:meth:`GainCertificate.check`).

    Attributes
    ----------
    direction : str
        ``"forward"`` or ``"backward"``.
    reach : float
        The largest delay of that direction in use, in seconds.
    bound : float
        The certificate's bound there, in seconds.
    """

    direction: str = ""
    reach: float = math.nan
    bound: float = math.nan


@dataclass(frozen=True)
class GainCertificate:
    """Verdict on a gain box for given delay bounds.

    Parameters
    ----------
    certified : bool
        Whether every gain of the box (varying as ``gain_variation`` says) is certified stable.
    method : str
        Certification method (``"nuno"`` or ``"lmi"``).
    gain_variation : str
        The gain class (:mod:`teleopkit.certification.gain_classes`), for example ``"frozen"`` or
        ``"scheduled:1"``.
    delay_bounds : tuple of float
        ``(T_l*, T_r*)``.
    delay_margin : float
        Largest common bound ``T* = T_l* = T_r*`` for which the whole box is certified.
    box : GainBox
        The box asked about.
    polytope : GainPolytope
        Gains inside the box offered to the safety layer; may be smaller than the box.
    polytope_certified : bool
        Whether ``polytope`` itself is certified (it can be when the box is not).
    assumptions : tuple of str
        What the verdict rests on.
    violation : str or None
        When not certified: the violating vertex and condition.
    details : mapping
        Method-specific data (for the LMI, the solver's certificate as JSON-ready data); kept
        as a read-only view.
    plant : mapping
        The plant certified (:func:`~teleopkit.model.records.plant_record`); read-only.
    delay_lower : tuple of float
        ``(T_l_min, T_r_min)``: the delays certified lie in ``[T_i_min, T_i*]`` (0: from 0).
    other_plants : tuple of mapping
        Further plants the same verdict is certified for (a closed-form certificate derived
        again for each gives the same set:
        :func:`~teleopkit.certification.verification.cover_plants`); empty for one plant.
    plant_ranges : tuple of mapping
        The range of each plant of ``(plant, *other_plants)`` (a
        :meth:`~teleopkit.model.plant_range.PlantRange.to_record`, empty for none): the
        certificate covers every plant of those ranges. Empty when no plant has one.
    """

    certified: bool
    method: str
    gain_variation: str
    delay_bounds: tuple[float, float]
    delay_margin: float
    box: GainBox
    polytope: GainPolytope
    polytope_certified: bool
    assumptions: tuple[str, ...]
    violation: str | None = None
    details: Mapping[str, Any] = field(default_factory=dict)
    plant: Mapping[str, Any] = field(default_factory=dict)
    delay_lower: tuple[float, float] = (0.0, 0.0)
    other_plants: tuple[Mapping[str, Any], ...] = ()
    plant_ranges: tuple[Mapping[str, Any], ...] = ()
    _variation: GainVariation = field(init=False, repr=False, compare=False)
    _scheduled: ScheduledSet | None = field(init=False, repr=False, compare=False)
    _ranges: tuple[PlantRange, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # a value: its mappings are read-only views of copies
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))
        object.__setattr__(self, "plant", MappingProxyType(dict(self.plant)))
        object.__setattr__(self, "other_plants", tuple(MappingProxyType(dict(record))
                                                       for record in self.other_plants))
        ranges = tuple(PlantRange.from_record(record) for record in self.plant_ranges)
        if ranges and len(ranges) != 1 + len(self.other_plants):
            raise ValueError(f"plant_ranges has {len(ranges)} entries for "
                             f"{1 + len(self.other_plants)} plants")
        if not any(ranges):
            ranges = (PlantRange(),) * (1 + len(self.other_plants))
        object.__setattr__(self, "_ranges", ranges)
        object.__setattr__(self, "plant_ranges", tuple(
            MappingProxyType(interval.to_record()) for interval in ranges)
            if any(ranges) else ())
        # the parsed forms are computed once, here (a bad class or set fails at construction)
        object.__setattr__(self, "_variation", parse_gain_variation(self.gain_variation))
        data = self.details.get("set")
        object.__setattr__(self, "_scheduled", None if data is None
                           else ScheduledSet.from_dict(data))

    @property
    def variation(self) -> GainVariation:
        """The gain class, parsed."""
        return self._variation

    @property
    def scheduled_set(self) -> ScheduledSet | None:
        """The set of a scheduled class (``details["set"]``), None for the other classes."""
        return self._scheduled

    def guarantee(self, start: InitialState | Start | None = None) -> StorageGuarantee | None:
        """What a scheduled class's storage bound allows from a start, in the plant's units.

        Parameters
        ----------
        start : InitialState, StartSpec or StartMix, optional
            Initial positions (velocities zero, the past held): fixed, drawn from ranges or one
            of several (the ``start`` of a :class:`~teleopkit.setup.Setup`), the bounds holding
            from every one of them. The paper's start by default (two joints only).

        Returns
        -------
        StorageGuarantee or None
            Largest spring deflection, speeds and position mismatch along every run of the
            class (:mod:`teleopkit.certification.nuno.guarantee`), for every plant the
            certificate covers (its other plants and ranges too); None for the other classes
            or an empty set.

        Raises
        ------
        ValueError
            If no start is given for a plant that does not have two joints, or the start's
            joints are not the plant's.
        """
        allowed, storage = self.scheduled_set, self.storage
        if allowed is None or storage is None or allowed.is_empty:
            return None
        if start is None and self.box.n_joints != 2:
            raise ValueError(f"a guarantee of a {self.box.n_joints}-joint plant needs its start "
                             "(the paper's start has two joints)")
        if not isinstance(start, StartSpec | StartMix):
            start = StartSpec.fixed(start or InitialState())
        return StorageGuarantee.worst([
            storage_guarantee(plant_params(record), storage, allowed, self.variation, interval,
                              start)
            for record, interval in zip((self.plant, *self.other_plants), self.ranges,
                                        strict=True)])

    @property
    def storage(self) -> ScheduledStorage | None:
        """The Lyapunov storage of a scheduled class (``details["storage"]``), else None."""
        data = self.details.get("storage")
        return None if data is None else ScheduledStorage.from_details(data)

    @property
    def ranges(self) -> tuple[PlantRange, ...]:
        """The range of each recorded plant, ``(plant, *other_plants)`` (empty where none)."""
        return self._ranges

    def covers_plant(self, params: TeleoperatorParams) -> bool:
        """Whether ``params`` is one of the recorded plants, or lies in the range of one.

        Parameters
        ----------
        params : TeleoperatorParams
            A plant.

        Returns
        -------
        bool
            True when one of the recorded plants (or ranges) holds ``params``.
        """
        return any(interval.covers(record, params) for record, interval in
                   zip((self.plant, *self.other_plants), self.ranges, strict=True))

    def check(self, params: TeleoperatorParams | Sequence[TeleoperatorParams],
              forward_bound: float | None = None, backward_bound: float | None = None,
              floors: tuple[float, float] = (0.0, 0.0), units_hint: bool = True) -> None:
        """Refuse the certificate for a plant it does not cover or for delays outside its bounds.

        Parameters
        ----------
        params : TeleoperatorParams or sequence of them
            The plant (or plants) it is to be used on.
        forward_bound, backward_bound : float, optional
            Declared upper bounds of the delay profiles in use (seconds).
        floors : tuple of float
            Declared lower bounds of the forward and backward profiles (seconds): a certificate
            for delays from ``T_i_min > 0`` is refused for profiles that can fall below it.
        units_hint : bool
            Whether a refusal of the delay bounds may suggest a value was meant in
            milliseconds (only where one was typed without a unit).

        Raises
        ------
        DelayBoundError
            One line, for delays that can exceed the bounds.
        ValueError
            One line naming the difference, for another plant or delays below the floors.
        """
        if not self.plant:
            raise ValueError("the certificate names no plant; certify again with this teleopkit")
        records = (self.plant, *self.other_plants)
        # a refusal names the difference from the first plant with a range, else the first
        shown = next((k for k, interval in enumerate(self.ranges) if interval), 0)
        for plant in (params,) if isinstance(params, TeleoperatorParams) else params:
            if not self.covers_plant(plant):
                mismatch = self.ranges[shown].mismatch(records[shown], plant)
                raise ValueError(mismatch if len(records) == 1 else
                                 f"the plant is none of the certificate's {len(records)} plants "
                                 f"or their ranges (against plant {shown + 1}: {mismatch})")
        for name, bound, certified in (("forward", forward_bound, self.delay_bounds[0]),
                                       ("backward", backward_bound, self.delay_bounds[1])):
            if bound is not None and bound > certified:
                hint = (" (delays in seconds: a value in milliseconds needs the ms unit)"
                        if units_hint else "")
                error = DelayBoundError(f"the {name} delay can reach {bound:.6g} s, beyond the "
                                        f"certificate's bound {certified:g} s{hint}")
                error.direction, error.reach, error.bound = name, bound, certified
                raise error
        for name, floor, certified in zip(("forward", "backward"), floors, self.delay_lower,
                                          strict=True):
            if floor < certified:
                raise ValueError(f"the {name} delay can fall to {floor:.6g} s, below the "
                                 f"certificate's minimum delay {certified:g} s")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (what ``teleopkit certify --json`` prints)."""
        n = self.box.n_joints
        return {
            "certified": self.certified,
            "method": self.method,
            "gain_variation": self.gain_variation,
            "delay_bounds": list(self.delay_bounds),
            "delay_margin": _json_float(self.delay_margin),
            "box": self.box.to_dict(),
            "polytope": {**self.polytope.to_dict(),
                         "joint_vertices": [self.polytope.joint_vertices(i).tolist()
                                            for i in range(n)]},
            "polytope_certified": self.polytope_certified,
            "assumptions": list(self.assumptions),
            "violation": self.violation,
            "details": dict(self.details),
            "plant": dict(self.plant),
            "delay_lower": list(self.delay_lower),
            **({"other_plants": [dict(record) for record in self.other_plants]}
               if self.other_plants else {}),
            **({"plant_ranges": [dict(record) for record in self.plant_ranges]}
               if self.plant_ranges else {}),
        }

    def to_json(self, indent: int | None = 2) -> str:
        """JSON text of :meth:`to_dict`.

        Parameters
        ----------
        indent : int or None
            Indentation passed to :func:`json.dumps`; None for a single line.

        Returns
        -------
        str
            The certificate as JSON (an infinite delay margin as the string ``"inf"``).
        """
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_json(cls, text: str | os.PathLike[str]) -> GainCertificate:
        """Inverse of :meth:`to_json`: parse (a file's text, given its path), nothing more.

        A parsed certificate is a claim. Reading one for use goes through
        :func:`~teleopkit.certification.verification.load_certificate`, which parses and
        re-checks it.

        Parameters
        ----------
        text : str or os.PathLike
            JSON text as :meth:`to_json` writes it, or the path of a file holding it: a path
            object, or a string naming an existing file or shaped like a path (one line with
            ``/`` in it or ``.json`` at its end, not starting with ``{``).

        Returns
        -------
        GainCertificate
            The certificate, not re-checked.

        Raises
        ------
        ValueError
            One line naming what is malformed, or a file that is missing or unreadable.
        TypeError
            If ``text`` is neither a string nor a path.
        """
        source = _json_text(text)
        try:
            data = json.loads(source)
            ranges = data["box"]
            box = GainBox(tuple(map(tuple, ranges["kr"])), tuple(map(tuple, ranges["br"])))
            margin = data["delay_margin"]
            return cls(
                certified=bool(data["certified"]), method=str(data["method"]),
                gain_variation=str(data["gain_variation"]),
                delay_bounds=tuple(data["delay_bounds"]),
                delay_margin=math.inf if margin == "inf" else float(margin), box=box,
                polytope=GainPolytope.from_dict(data["polytope"]),
                polytope_certified=bool(data["polytope_certified"]),
                assumptions=tuple(data["assumptions"]), violation=data["violation"],
                details=dict(data["details"]), plant=dict(data.get("plant", {})),
                delay_lower=_delay_lower(data.get("delay_lower", (0.0, 0.0))),
                other_plants=tuple(dict(record) for record in data.get("other_plants", ())),
                plant_ranges=tuple(dict(record) for record in data.get("plant_ranges", ())))
        except (KeyError, TypeError, ValueError, json.JSONDecodeError) as error:
            raise ValueError(f"malformed gain certificate: {error}") from None


def _names_file(text: str) -> bool:
    """Whether ``text`` is a path, not JSON: one line, no ``{``, a file's name or a path's shape."""
    if text.lstrip()[:1] in ("{", "") or "\n" in text.strip():
        return False
    return text.endswith(".json") or "/" in text or os.sep in text or os.path.isfile(text)


def _json_text(source: str | bytes | os.PathLike[str]) -> str | bytes:
    """``source`` if it is JSON text (:func:`_names_file`), else the text of the file it names."""
    if isinstance(source, bytes | bytearray) or (isinstance(source, str)
                                                 and not _names_file(source)):
        return source
    if not isinstance(source, str | os.PathLike):
        raise TypeError(f"text must be a certificate's JSON text or a path, got "
                        f"{type(source).__name__}")
    try:
        return Path(source).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"no such certificate file: {os.fspath(source)} (give a certificate "
                         "file or its JSON text)") from None
    except (OSError, ValueError) as error:  # a directory, unreadable, not UTF-8
        reason = getattr(error, "strerror", None) or str(error)
        raise ValueError(f"cannot read certificate file {os.fspath(source)}: {reason}") from None


def _delay_lower(values: Any) -> tuple[float, float]:
    """The recorded minimum delays, checked: two finite non-negative numbers."""
    lower = tuple(float(v) for v in values)
    if len(lower) != 2 or not all(math.isfinite(v) and v >= 0 for v in lower):
        raise ValueError(f"delay_lower must be two non-negative numbers, got {list(values)}")
    return lower[0], lower[1]


def _json_float(value: float) -> float | str:
    return "inf" if value == math.inf else value
