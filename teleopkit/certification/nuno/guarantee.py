r"""What the storage bound of a scheduled class allows, in the plant's own units.

Along every run of a scheduled class the storage :math:`V` of
:mod:`teleopkit.certification.nuno.lyapunov` obeys :math:`V(t) \le \bar V`, with
:math:`\bar V = V(0)` for ``scheduled:0`` (the stiffness never falls), :math:`e^L V(0)` for
``scheduled:L`` and :math:`V(0) + T_0` with a tank of initial level :math:`T_0` (the tank is
never negative). Every term of :math:`V` is non-negative, so each one is bounded by
:math:`\bar V` on its own, and with :math:`\kappa(t) \le \kappa_{max}`:

- spring deflection: :math:`\tfrac12 S_i (q_{r,i} - \theta_i)^2 \le E_r \le \kappa \bar V`;
- motor speed: :math:`\tfrac12 J_i \dot\theta_i^2 \le \kappa \bar V`;
- link speed: :math:`\tfrac12 \lambda_{min}(M_r) |\dot q_r|^2 \le \kappa \bar V`;
- local speed: :math:`\tfrac12 \lambda_{min}(M_l) |\dot q_l|^2 \le k_l \bar V`;
- position mismatch: :math:`\tfrac12 s_i (q_{l,i} - \theta_i)^2 \le \bar V`.

:math:`V(0)` is evaluated at a start (initial positions, velocities zero, the past held) with
the smallest stiffness of the class, which makes it largest. A start drawn from ranges, or one
of several starts (a setup's :class:`~teleopkit.setup.StartSpec` or
:class:`~teleopkit.setup.StartMix`), takes the largest :math:`V(0)` over all of them: at rest
every term of :math:`V` is convex and belongs to one joint, so the largest value lies at a
corner of each box of positions, every joint at its own worst corner (exact, ``8 n``
evaluations per box).

A plant whose parameters lie in ranges (:class:`~teleopkit.model.plant_range.PlantRange`) gets
bounds that hold for every plant of the ranges: at rest the storage's remote part is the joint
springs' energy, linear in their stiffness and free of the inertias, so :math:`V(0)` is largest
with every ranged value at its upper end; the spring and rotor bounds take the lowest stiffness
and rotor inertia; the link-speed bound takes the smallest :math:`\lambda_{min}(M_r)` with the
masses and link inertias at their lower ends (the kinetic energy grows with each of them) over
the ends and middles of any ranged lengths and centres of mass (a grid, as the configurations
are). Several plants get the largest bound of each. A certificate does not
record a start (no stability proof depends on one):
:meth:`~teleopkit.certification.gain_certificate.GainCertificate.guarantee` takes it (the
paper's by default, for two joints). The bounds hold for a passive
operator and environment (an operator holding its reference at the origin: a moving reference
is an active source of energy, whose work the storage does not count).

A tank can be asked for as the deflection it allows: ``tank:0.5rad`` is the tank whose bound
lets the spring deflect by at most 0.5 rad from the start (:func:`resolve_tank`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.nuno.lyapunov import ScheduledStorage
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.params import PlanarArm, TeleoperatorParams
from teleopkit.model.plant_range import PlantRange, value_of, with_values
from teleopkit.setup.start import StartMix, StartSpec
from teleopkit.sim.energy import local_energy, remote_energy
from teleopkit.sim.state import StateLayout

__all__ = ["Start", "StorageGuarantee", "resolve_tank", "start_storage", "storage_guarantee"]


Start = StartSpec | StartMix
"""Starts a guarantee holds from: one box of initial positions, or several."""


def _storage_at(params: TeleoperatorParams, storage: ScheduledStorage, kappa: float,
                positions: np.ndarray) -> np.ndarray:
    """``V(0)`` at rest at initial positions ``(..., 3, n)`` (rows ``q_l, q_r, theta``)."""
    layout = StateLayout(params.n_joints)
    state = np.zeros((*positions.shape[:-2], layout.size))
    for row, name in enumerate(("ql", "qr", "theta")):
        state[..., layout.slice(name)] = positions[..., row, :]
    stretch = positions[..., 0, :] - positions[..., 2, :]
    return (local_energy(params, state) / storage.normaliser
            + remote_energy(params, state) / kappa
            + 0.5 * np.sum(np.array(storage.shape) * stretch**2, axis=-1))


def _largest_in_box(params: TeleoperatorParams, storage: ScheduledStorage, kappa: float,
                    low: np.ndarray, high: np.ndarray) -> float:
    """The largest ``V(0)`` over a box of initial positions (exact).

    At rest every term of ``V`` (the operator's and the joint springs, a wall's spring, the
    stretch term) is convex and belongs to one joint: the largest value is at a corner of the
    box, each joint at its own worst corner of its three positions.
    """
    corners = np.array(list(itertools.product((False, True), repeat=3)))  # (8, 3)
    worst = low.copy()
    for i in range(params.n_joints):
        candidates = np.repeat(worst[None], len(corners), axis=0)
        candidates[:, :, i] = np.where(corners, high[:, i], low[:, i])
        worst = candidates[int(np.argmax(_storage_at(params, storage, kappa, candidates)))]
    return float(_storage_at(params, storage, kappa, worst))


def start_storage(params: TeleoperatorParams, storage: ScheduledStorage, kappa: float,
                  ranges: PlantRange | None = None, start: Start | None = None) -> float:
    """``V(0)`` at rest at the start with the stiffness ``kappa``: its largest value.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (its initial state unless ``start`` is given).
    storage : ScheduledStorage
        The storage.
    kappa : float
        The first applied ``kappa`` (positive).
    ranges : PlantRange, optional
        Ranges of the remote plant's parameters around ``params``: the largest ``V(0)`` over
        them (at their upper ends, see the module's text).
    start : StartSpec or StartMix, optional
        Initial positions, fixed or ranges: the largest ``V(0)`` over all of them (exact: at
        a corner of each box). Default: ``params.initial``.

    Returns
    -------
    float
        The storage at ``t = 0`` (the double integrals are zero: the past is held).
    """
    boxes = (start or StartSpec.fixed(params.initial)).boxes
    if boxes[0][0].shape[1] != params.n_joints:
        raise ValueError(f"the start has {boxes[0][0].shape[1]} joints, the plant "
                         f"{params.n_joints}")
    return max(_largest_in_box(plant, storage, kappa, low, high)
               for plant in _ends(params, ranges) for low, high in boxes)


def _ends(params: TeleoperatorParams, ranges: PlantRange | None) -> tuple[TeleoperatorParams, ...]:
    """The plant and, with ranges, the plants with every ranged value at its lower and upper end."""
    return (params, *ranges.corners(params)) if ranges else (params,)


def _softest_starts(params: TeleoperatorParams, storage: ScheduledStorage, kappa: float,
                    ranges: PlantRange | None, start: Start | None) -> np.ndarray:
    """Per joint ``i``, ``V(0)`` where joint ``i``'s deflection bound is largest over the ranges.

    The bound grows as ``V(0) / S_i``, and ``V(0)`` is linear in every joint's stiffness: its
    largest value is with joint ``i``'s spring at its softest and the others at their stiffest.
    """
    n = params.n_joints
    if not ranges or "joints.stiffness" not in ranges.bounds:
        return np.full(n, start_storage(params, storage, kappa, ranges, start))
    low, high = ranges.bounds["joints.stiffness"]
    stiffest = ranges.corners(params)[1]
    return np.array([start_storage(with_values(stiffest, {"joints.stiffness": (
        *high[:i], low[i], *high[i + 1:])}), storage, kappa, start=start) for i in range(n)])


def _least(params: TeleoperatorParams, ranges: PlantRange | None, name: str) -> np.ndarray:
    """Per joint, the smallest value of ``name`` (``"joints.stiffness"``, ...) over the ranges."""
    return np.min([value_of(plant, name) for plant in _ends(params, ranges)], axis=0)


def _least_remote_inertia(params: TeleoperatorParams, ranges: PlantRange | None) -> float:
    """The smallest eigenvalue of the remote ``M(q)`` over configurations and ranges.

    Masses and link inertias at their lower ends (``M`` grows with each in the Loewner order);
    ranged lengths and centres of mass at the ends and middles of their intervals, every
    combination.
    """
    if not ranges:
        return _least_inertia(params.remote_arm)
    lightest = ranges.corners(params)[0]
    shaped = {name: interval for name, interval in ranges.bounds.items()
              if name in ("remote_arm.lengths", "remote_arm.com")}
    grids = [list(itertools.product(*((lo, (lo + hi) / 2, hi)
                                      for lo, hi in zip(*interval, strict=True))))
             for interval in shaped.values()]  # each name's per-joint values
    arms = (with_values(lightest, dict(zip(shaped, values, strict=True))).remote_arm
            for values in itertools.product(*grids))
    return min(_least_inertia(arm) for arm in arms)


def _least_inertia(arm: PlanarArm, samples: int = 721) -> float:
    """The smallest eigenvalue of ``M(q)`` over the arm's configurations (a grid of angles)."""
    n = arm.n_joints
    grid = np.linspace(-math.pi, math.pi, samples if n == 2 else 64)
    angles = np.array(list(itertools.product(grid, repeat=n - 1)), dtype=float)
    q = np.concatenate([np.zeros((len(angles), 1)), angles], axis=1)  # M(q) is free of q_1
    return float(np.linalg.eigvalsh(mass_matrix(arm, q))[:, 0].min())


@dataclass(frozen=True)
class StorageGuarantee:
    """The bounds a scheduled class's storage gives from a start.

    Attributes
    ----------
    storage_start : float
        ``V(0)`` at the plant's initial state and the class's smallest stiffness.
    storage_bound : float
        ``V_bar``: ``V(t) <= V_bar`` along every run of the class.
    kappa_max : float
        The largest stiffness of the class.
    deflection : tuple of float
        Largest spring deflection ``|q_r,i - theta_i|`` of each joint (rad).
    motor_speed : tuple of float
        Largest motor speed ``|theta_i'|`` of each joint (rad/s).
    link_speed : float
        Largest remote link speed ``|q_r'|`` (rad/s, Euclidean over joints).
    local_speed : float
        Largest local speed ``|q_l'|`` (rad/s, Euclidean over joints).
    mismatch : tuple of float
        Largest position mismatch ``|q_l,i - theta_i|`` of each joint (rad).
    """

    storage_start: float
    storage_bound: float
    kappa_max: float
    deflection: tuple[float, ...]
    motor_speed: tuple[float, ...]
    link_speed: float
    local_speed: float
    mismatch: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON)."""
        return {key: list(value) if isinstance(value, tuple) else value
                for key, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StorageGuarantee:
        """Inverse of :meth:`to_dict`.

        Parameters
        ----------
        data : dict
            As :meth:`to_dict` writes it.

        Returns
        -------
        StorageGuarantee
            The bounds.
        """
        return cls(**{key: tuple(value) if isinstance(value, list) else value  # type: ignore[arg-type]
                      for key, value in data.items()})

    @classmethod
    def worst(cls, guarantees: Sequence[StorageGuarantee]) -> StorageGuarantee:
        """The largest value of every bound over several plants' guarantees.

        Parameters
        ----------
        guarantees : sequence of StorageGuarantee
            One per plant (at least one), of the same class and number of joints.

        Returns
        -------
        StorageGuarantee
            Bounds that hold for each of the plants.
        """
        rows = [g.to_dict() for g in guarantees]
        return cls.from_dict({key: (np.max([r[key] for r in rows], axis=0).tolist()
                                    if isinstance(rows[0][key], list)
                                    else max(r[key] for r in rows)) for key in rows[0]})

    def describe(self) -> str:
        """One line in the plant's units."""
        def joints(values: tuple[float, ...]) -> str:
            return ", ".join(f"{v:.3g}" for v in values)

        return (f"from the start (V(0) = {self.storage_start:.4g}, bound "
                f"{self.storage_bound:.4g}, kappa <= {self.kappa_max:g}): spring deflection "
                f"<= {joints(self.deflection)} rad, motor speed <= {joints(self.motor_speed)} "
                f"rad/s, link speed <= {self.link_speed:.3g} rad/s, local speed <= "
                f"{self.local_speed:.3g} rad/s, position mismatch |q_l - theta| <= "
                f"{joints(self.mismatch)} rad (passive operator and environment)")


def _bound_factor(variation: GainVariation, start: float) -> float:
    """``V_bar`` of a class from ``V(0)``."""
    if variation.kind == "scheduled":
        return math.exp(variation.value) * start
    return start + variation.value


def storage_guarantee(params: TeleoperatorParams, storage: ScheduledStorage,
                      allowed: ScheduledSet, variation: GainVariation,
                      ranges: PlantRange | None = None, start: Start | None = None,
                      ) -> StorageGuarantee:
    """The bounds of :class:`StorageGuarantee` for a scheduled class.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    storage : ScheduledStorage
        Its storage for the delay bounds.
    allowed : ScheduledSet
        The class's set (its ``kappa`` range).
    variation : GainVariation
        ``scheduled:L`` or ``tank:T0`` (a tank in storage units, :func:`resolve_tank`).
    ranges : PlantRange, optional
        Ranges of the remote plant's parameters around ``params``: bounds for every plant of
        them (see the module's text).
    start : StartSpec or StartMix, optional
        Initial positions, fixed or ranges: bounds from every one of them. Default:
        ``params.initial``.

    Returns
    -------
    StorageGuarantee
        The bounds.
    """
    largest = start_storage(params, storage, allowed.kappa_low, ranges, start)
    bound = _bound_factor(variation, largest)
    kappa = allowed.kappa_high
    energy = kappa * bound  # E_r <= kappa V_bar
    springs = [kappa * _bound_factor(variation, joint_start) for joint_start in
               _softest_starts(params, storage, allowed.kappa_low, ranges, start)]
    spring = _least(params, ranges, "joints.stiffness")
    rotor = _least(params, ranges, "joints.rotor_inertia")
    shape = np.array(storage.shape)
    return StorageGuarantee(
        largest, bound, kappa, tuple(np.sqrt(2 * np.array(springs) / spring).tolist()),
        tuple(np.sqrt(2 * energy / rotor).tolist()),
        math.sqrt(2 * energy / _least_remote_inertia(params, ranges)),
        math.sqrt(2 * storage.normaliser * bound / _least_inertia(params.local_arm)),
        tuple(np.sqrt(2 * bound / shape).tolist()))


def resolve_tank(params: TeleoperatorParams | Sequence[TeleoperatorParams],
                 storage: ScheduledStorage, allowed: ScheduledSet, variation: GainVariation,
                 ranges: Sequence[PlantRange] = (), start: Start | None = None,
                 ) -> GainVariation:
    """A tank asked for as a deflection (``tank:0.5rad``) as its initial level ``T0``.

    The level is the one whose bound ``V(0) + T0`` allows that spring deflection at the class's
    largest stiffness on the softest joint spring (the others deflect less); for several plants
    or ranges, the smallest such level (every plant deflects at most that much). It is rounded
    down to six significant digits, as the certificate records it.

    Parameters
    ----------
    params : TeleoperatorParams or sequence of TeleoperatorParams
        Teleoperator, or every plant the certificate covers (one storage serves them all).
    storage : ScheduledStorage
        Its storage.
    allowed : ScheduledSet
        The class's set.
    variation : GainVariation
        The class; returned unchanged unless it is a tank given in ``rad``.
    ranges : sequence of PlantRange, optional
        The range of each plant; none by default.
    start : StartSpec or StartMix, optional
        Initial positions, fixed or ranges: the deflection holds from every one of them.
        Default: each plant's ``initial``.

    Returns
    -------
    GainVariation
        ``tank:T0`` in storage units.

    Raises
    ------
    ValueError
        If the deflection is below what the start alone allows (no tank gives it).
    """
    if variation.kind != "tank" or variation.unit != "rad":
        return variation
    plants = [params] if isinstance(params, TeleoperatorParams) else list(params)
    levels, least = [], 0.0
    for plant, interval in zip(plants, tuple(ranges) or (None,) * len(plants), strict=True):
        starts = _softest_starts(plant, storage, allowed.kappa_low, interval, start)
        spring = _least(plant, interval, "joints.stiffness")
        levels.append(float(np.min(spring * variation.value**2 / (2 * allowed.kappa_high)
                                   - starts)))
        least = max(least, float(np.max(np.sqrt(2 * allowed.kappa_high * starts / spring))))
    if min(levels) < 0:
        raise ValueError(f"a tank allowing {variation.value:g} rad of spring deflection does "
                         f"not exist: the start alone allows {least:.4g} rad (ask for more)")
    return GainVariation("tank", _round_down(min(levels)))


def _round_down(value: float, digits: int = 6) -> float:
    """``value`` rounded down to ``digits`` significant digits.

    A certificate records its class as text (six significant digits); the level it records
    must read back as the level its set was derived with, and may only be smaller.
    """
    if value == 0:
        return 0.0
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(value)))
    return math.floor(value * scale) / scale
