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

:math:`V(0)` is evaluated at a start (the plant's initial positions, velocities zero, the past
held) with the smallest stiffness of the class, which makes it largest. A certificate does not
record a start (no stability proof depends on one):
:meth:`~teleopkit.certification.gain_certificate.GainCertificate.guarantee` takes it, the
paper's by default. The bounds hold for a passive
operator and environment (an operator holding its reference at the origin: a moving reference
is an active source of energy, whose work the storage does not count).

A tank can be asked for as the deflection it allows: ``tank:0.5rad`` is the tank whose bound
lets the spring deflect by at most 0.5 rad from the plant's start (:func:`resolve_tank`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from teleopkit.certification.gain_classes import GainVariation
from teleopkit.certification.nuno.lyapunov import ScheduledStorage
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.params import PlanarArm, TeleoperatorParams
from teleopkit.sim.energy import local_energy, remote_energy
from teleopkit.sim.state import StateLayout

__all__ = ["StorageGuarantee", "resolve_tank", "start_storage", "storage_guarantee"]


def _start_state(params: TeleoperatorParams) -> np.ndarray:
    """The plant's initial state as a state vector (velocities and integrals zero)."""
    layout = StateLayout(params.n_joints)
    state = np.zeros(layout.size)
    state[layout.slice("ql")] = params.initial.local
    state[layout.slice("qr")] = params.initial.remote
    state[layout.slice("theta")] = params.initial.motor
    return state


def start_storage(params: TeleoperatorParams, storage: ScheduledStorage, kappa: float) -> float:
    """``V(0)`` at the plant's initial state with the stiffness ``kappa``.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (its initial state).
    storage : ScheduledStorage
        The storage.
    kappa : float
        The first applied ``kappa`` (positive).

    Returns
    -------
    float
        The storage at ``t = 0`` (the double integrals are zero: the past is held).
    """
    state = _start_state(params)
    shape = np.array(storage.shape)
    stretch = np.array(params.initial.local) - np.array(params.initial.motor)
    return float(local_energy(params, state) / storage.normaliser
                 + remote_energy(params, state) / kappa + 0.5 * np.sum(shape * stretch**2))


def _least_inertia(arm: PlanarArm, samples: int = 721) -> float:
    """The smallest eigenvalue of ``M(q)`` over the arm's configurations (a grid of angles)."""
    n = arm.n_joints
    grid = np.linspace(-math.pi, math.pi, samples if n == 2 else 64)
    angles = np.stack(np.meshgrid(*([grid] * (n - 1)), indexing="ij"), -1).reshape(-1, n - 1)
    q = np.concatenate([np.zeros((len(angles), 1)), angles], axis=1)
    return float(np.linalg.eigvalsh(mass_matrix(arm, q))[:, 0].min())


@dataclass(frozen=True)
class StorageGuarantee:
    """The bounds a scheduled class's storage gives from the plant's start.

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

    def describe(self) -> str:
        """One line in the plant's units."""
        def joints(values: tuple[float, ...]) -> str:
            return ", ".join(f"{v:.3g}" for v in values)

        return (f"from the plant's start (V(0) = {self.storage_start:.4g}, bound "
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
                      allowed: ScheduledSet, variation: GainVariation) -> StorageGuarantee:
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

    Returns
    -------
    StorageGuarantee
        The bounds.
    """
    start = start_storage(params, storage, allowed.kappa_low)
    bound = _bound_factor(variation, start)
    kappa = allowed.kappa_high
    energy = kappa * bound  # E_r <= kappa V_bar
    spring = np.array(params.joints.stiffness)
    rotor = np.array(params.joints.rotor_inertia)
    shape = np.array(storage.shape)
    return StorageGuarantee(
        start, bound, kappa, tuple(np.sqrt(2 * energy / spring).tolist()),
        tuple(np.sqrt(2 * energy / rotor).tolist()),
        math.sqrt(2 * energy / _least_inertia(params.remote_arm)),
        math.sqrt(2 * storage.normaliser * bound / _least_inertia(params.local_arm)),
        tuple(np.sqrt(2 * bound / shape).tolist()))


def resolve_tank(params: TeleoperatorParams, storage: ScheduledStorage, allowed: ScheduledSet,
                 variation: GainVariation) -> GainVariation:
    """A tank asked for as a deflection (``tank:0.5rad``) as its initial level ``T0``.

    The level is the one whose bound ``V(0) + T0`` allows exactly that spring deflection at the
    class's largest stiffness on the softest joint spring (the others deflect less).

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    storage : ScheduledStorage
        Its storage.
    allowed : ScheduledSet
        The class's set.
    variation : GainVariation
        The class; returned unchanged unless it is a tank given in ``rad``.

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
    start = start_storage(params, storage, allowed.kappa_low)
    spring = float(np.min(params.joints.stiffness))
    level = spring * variation.value**2 / (2 * allowed.kappa_high) - start
    if level < 0:
        least = math.sqrt(2 * allowed.kappa_high * start / spring)
        raise ValueError(f"a tank allowing {variation.value:g} rad of spring deflection does "
                         f"not exist: the start alone allows {least:.4g} rad (ask for more)")
    return GainVariation("tank", level)
