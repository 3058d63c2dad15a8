"""Ranges of the remote plant's parameters: a plant drawn per scenario, and what covers it.

A robot's payload, its links' masses, its joints' stiffness or its rotors are seldom known
exactly. A :class:`PlantRange` gives an interval for each joint's value of some of the remote
side's parameters (:data:`RANGED`); every scenario draws its plant uniformly from the box they
span, around a *nominal* plant (the midpoints). The local side has no range: its gains set the
closed-form certificate's set, and its arm is the device in the operator's hand.

The same value records, in a certificate, which plants the certificate covers: a plant is
covered when it equals the nominal plant but for ranged values inside their intervals
(:meth:`PlantRange.covers`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.records import PLANT_LABELS, plant_mismatch, plant_params, plant_record

__all__ = ["RANGED", "PlantRange", "value_of", "with_values"]

RANGED = ("remote_arm.lengths", "remote_arm.masses", "remote_arm.com", "remote_arm.inertia",
          "joints.stiffness", "joints.rotor_inertia")
"""The parameters a range may cover (one interval per joint), in the order they are drawn."""

Interval = tuple[tuple[float, ...], tuple[float, ...]]


def value_of(params: TeleoperatorParams, name: str) -> tuple[float, ...] | None:
    """The per-joint values of ``name`` (``"part.field"``, for example ``"joints.stiffness"``).

    Parameters
    ----------
    params : TeleoperatorParams
        A plant.
    name : str
        A name of :data:`RANGED`.

    Returns
    -------
    tuple of float or None
        The values (None for an arm's ``com`` or ``inertia`` left out).
    """
    part, key = name.split(".")
    return getattr(getattr(params, part), key)


def with_values(params: TeleoperatorParams, values: Mapping[str, tuple[float, ...]]
                ) -> TeleoperatorParams:
    """``params`` with the named per-joint values replaced.

    Parameters
    ----------
    params : TeleoperatorParams
        A plant.
    values : mapping of str to tuple of float
        ``name -> per-joint values`` for names of :data:`RANGED`.

    Returns
    -------
    TeleoperatorParams
        The plant with those values.
    """
    parts: dict[str, dict[str, tuple[float, ...]]] = {}
    for name, value in values.items():
        part, key = name.split(".")
        parts.setdefault(part, {})[key] = tuple(float(v) for v in value)
    return replace(params, **{part: replace(getattr(params, part), **changes)
                              for part, changes in parts.items()})


@dataclass(frozen=True)
class PlantRange:
    """Intervals of remote-plant parameters, one per joint, drawn uniformly per scenario.

    Parameters
    ----------
    bounds : mapping of str to (tuple of float, tuple of float)
        ``name -> (low, high)`` for names of :data:`RANGED`; per joint, ``low <= high``, both
        finite. Empty: no range (the plant is fixed).

    Examples
    --------
    >>> from teleopkit.model.params import TeleoperatorParams
    >>> heavier = PlantRange({"remote_arm.masses": ((0.5, 0.35), (0.7, 0.5))})
    >>> plants = heavier.draw(heavier.nominal(TeleoperatorParams()), 0, 3)
    >>> all(heavier.covers(heavier.nominal(TeleoperatorParams()), p) for p in plants)
    True
    """

    bounds: Mapping[str, Interval] = field(default_factory=dict)

    def __post_init__(self) -> None:
        checked: dict[str, Interval] = {}
        for name in RANGED:  # the draw order, whatever order they were given in
            if name not in self.bounds:
                continue
            low, high = (tuple(float(v) for v in side) for side in self.bounds[name])
            if len(low) != len(high) or not low:
                raise ValueError(f"{name}: min and max need one value per joint, got {len(low)} "
                                 f"and {len(high)}")
            if not all(math.isfinite(v) for v in (*low, *high)):
                raise ValueError(f"{name}: a range needs finite values")
            if any(h < lo for lo, h in zip(low, high, strict=True)):
                raise ValueError(f"{name}: max {list(high)} is below min {list(low)}")
            checked[name] = (low, high)
        unknown = sorted(set(self.bounds) - set(RANGED))
        if unknown:
            raise ValueError(f"{unknown[0]} cannot have a range (ranges are for "
                             f"{', '.join(RANGED)})")
        object.__setattr__(self, "bounds", MappingProxyType(checked))

    def __bool__(self) -> bool:
        return bool(self.bounds)

    def nominal(self, params: TeleoperatorParams) -> TeleoperatorParams:
        """``params`` with every ranged value at the middle of its interval.

        Parameters
        ----------
        params : TeleoperatorParams
            A plant with the range's number of joints.

        Returns
        -------
        TeleoperatorParams
            The nominal plant.
        """
        middles = {name: tuple((lo + h) / 2 for lo, h in zip(low, high, strict=True))
                   for name, (low, high) in self.bounds.items()}
        return with_values(params, middles)

    def corners(self, params: TeleoperatorParams) -> tuple[TeleoperatorParams, TeleoperatorParams]:
        """``params`` with every ranged value at its lower end, and at its upper end.

        Parameters
        ----------
        params : TeleoperatorParams
            A plant with the range's number of joints.

        Returns
        -------
        tuple of TeleoperatorParams
            The lowest and the highest plant.
        """
        return (with_values(params, {name: low for name, (low, _) in self.bounds.items()}),
                with_values(params, {name: high for name, (_, high) in self.bounds.items()}))

    def draw(self, params: TeleoperatorParams, rng: np.random.Generator | int,
             count: int) -> list[TeleoperatorParams]:
        """``count`` plants: ``params`` with each ranged value drawn uniformly in its interval.

        Parameters
        ----------
        params : TeleoperatorParams
            The plant whose other values the draws keep.
        rng : numpy.random.Generator or int
            Generator or seed (the parameters are drawn in the order of :data:`RANGED`).
        count : int
            Plants to draw.

        Returns
        -------
        list of TeleoperatorParams
            The plants.
        """
        rng = np.random.default_rng(rng)
        draws = {name: rng.uniform(low, high, size=(count, len(low)))
                 for name, (low, high) in self.bounds.items()}
        return [with_values(params, {name: tuple(values[k]) for name, values in draws.items()})
                for k in range(count)]

    def covers(self, nominal: TeleoperatorParams | Mapping[str, Any],
               params: TeleoperatorParams) -> bool:
        """Whether ``params`` is ``nominal`` but for ranged values inside their intervals.

        Parameters
        ----------
        nominal : TeleoperatorParams or mapping
            The nominal plant, or its :func:`~teleopkit.model.records.plant_record`.
        params : TeleoperatorParams
            A plant.

        Returns
        -------
        bool
            True when covered.
        """
        return self.mismatch(nominal, params) is None

    def mismatch(self, nominal: TeleoperatorParams | Mapping[str, Any],
                 params: TeleoperatorParams) -> str | None:
        """How ``params`` falls outside what :meth:`covers` accepts (None when covered).

        Parameters
        ----------
        nominal : TeleoperatorParams or mapping
            The nominal plant, or its :func:`~teleopkit.model.records.plant_record`.
        params : TeleoperatorParams
            A plant.

        Returns
        -------
        str or None
            One line naming the first value outside its range or differing from the nominal.
        """
        for name, (low, high) in self.bounds.items():
            value = value_of(params, name)
            if value is None or len(value) != len(low) or not all(
                    lo <= v <= h for lo, v, h in zip(low, value, high, strict=True)):
                return (f"the certificate covers {PLANT_LABELS[name]} from {list(low)} to "
                        f"{list(high)}, the plant has {None if value is None else list(value)}")
        if isinstance(nominal, TeleoperatorParams):
            record, fixed = plant_record(nominal), nominal
        else:
            record, fixed = nominal, plant_params(nominal)
        # the ranged values set to the nominal's, the rest as they are: the nominal plant
        return plant_mismatch(record, with_values(params, {name: value_of(fixed, name)
                                                     for name in self.bounds}))

    def to_record(self) -> dict[str, dict[str, list[float]]]:
        """Plain data: ``{name: {"min": [...], "max": [...]}}`` (what a certificate stores)."""
        return {name: {"min": list(low), "max": list(high)}
                for name, (low, high) in self.bounds.items()}

    @classmethod
    def from_record(cls, record: Mapping[str, Any] | None) -> PlantRange:
        """Inverse of :meth:`to_record` (None or empty: no range).

        Parameters
        ----------
        record : mapping or None
            ``{name: {"min": [...], "max": [...]}}``.

        Returns
        -------
        PlantRange
            The range.

        Raises
        ------
        ValueError
            If the record is malformed.
        """
        try:
            return cls({name: (tuple(item["min"]), tuple(item["max"]))
                        for name, item in (record or {}).items()})
        except (KeyError, TypeError) as error:
            raise ValueError(f"malformed plant range: {error}") from None

