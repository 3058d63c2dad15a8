"""Parameters of the teleoperator as frozen dataclasses.

Parameters never change during a run; the state lives elsewhere. Every class checks its values on
construction and raises :class:`ValueError` with a one-line message naming the bad field.
:func:`paper_setup` returns the configuration of the source paper, completed where the paper is
silent from the authors' simulation model (operator reference, initial state, torque limit);
:func:`one_joint_setup` is its first joint alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

__all__ = [
    "ElasticJoints",
    "InitialState",
    "Operator",
    "PDGains",
    "PlanarArm",
    "TeleoperatorParams",
    "Wall",
    "one_joint_setup",
    "paper_setup",
]


def _vector(name: str, values: float | Sequence[float],
            like: tuple[str, tuple[float, ...]] | None = None) -> tuple[float, ...]:
    """Finite floats, as many as the field ``like = (name, values)`` (a scalar repeated)."""
    n = len(like[1]) if like is not None else 1
    if np.isscalar(values):
        values = [float(values)] * n  # type: ignore[arg-type]
    out = tuple(float(v) for v in values)  # type: ignore[union-attr]
    if not out:
        raise ValueError(f"{name} must not be empty")
    if like is not None and len(out) != n:
        raise ValueError(f"{like[0]} and {name} need one per joint, got {n} and {len(out)} values")
    if not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name} must be finite, got {out}")
    return out


def _joint_fields(owner: Any, labels: Mapping[str, str]) -> int:
    """Store ``owner``'s per-joint fields (attribute: label) as vectors as long as the first."""
    like: tuple[str, tuple[float, ...]] | None = None
    for name, label in labels.items():
        object.__setattr__(owner, name, values := _vector(label, getattr(owner, name), like))
        like = like or (label, values)
    return len(values)


def _positive(name: str, values: tuple[float, ...], allow_zero: bool = False) -> None:
    bad = [v for v in values if v < 0 or (v == 0 and not allow_zero)]
    if bad:
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be {kind}, got {values}")


@dataclass(frozen=True)
class PlanarArm:
    """Planar serial arm of rigid links, no gravity and no friction.

    Each link carries its mass at a distance ``com`` from its joint along the link and turns with
    an inertia ``inertia`` about its centre of mass. The defaults are the paper's point masses at
    the link tips: ``com = lengths`` and zero link inertia, stored as ``None`` (the canonical
    form, which keeps :func:`plant_record` and its fingerprint as they were for point masses).

    Parameters
    ----------
    lengths : tuple of float
        Link lengths in metres, base to tip.
    masses : tuple of float
        Mass of each link, in kilograms.
    com : tuple of float, optional
        Distance of each link's centre of mass from its joint, in metres (non-negative). None,
        or values equal to ``lengths``, puts the masses at the link tips.
    inertia : tuple of float, optional
        Moment of inertia of each link about its own centre of mass, in kg m^2 (non-negative).
        None, or all zeros, makes point masses.

    Raises
    ------
    ValueError
        If a value is missing, not finite or negative, or if a link has neither a centre of mass
        off its joint nor an inertia (its rotation would carry no kinetic energy, and ``M(q)``
        could be singular).

    Examples
    --------
    >>> PlanarArm((0.38, 0.38), (0.5, 0.35), com=(0.38, 0.38)).com is None
    True
    >>> PlanarArm((0.38, 0.38), (0.5, 0.35), com=(0.19, 0.19), inertia=0.006).link_inertias
    (0.006, 0.006)
    """

    lengths: tuple[float, ...] = (0.38, 0.38)
    masses: tuple[float, ...] = (0.5, 0.35)
    com: tuple[float, ...] | None = None
    inertia: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        n = _joint_fields(self, {"lengths": "arm lengths", "masses": "arm masses"})
        _positive("arm lengths", self.lengths)
        _positive("arm masses", self.masses)
        self._canonical("com", self.lengths)
        self._canonical("inertia", (0.0,) * n)
        idle = [i + 1 for i in range(n) if self.centres[i] == 0 and self.link_inertias[i] == 0]
        if idle:
            raise ValueError(f"arm com or inertia must be positive on every link, links {idle} "
                             "have neither (no kinetic energy of their own)")

    def _canonical(self, name: str, default: tuple[float, ...]) -> None:
        """Check the optional field ``name``; store None when it equals its ``default``."""
        values = getattr(self, name)
        if values is not None:
            values = _vector(f"arm {name}", values, ("arm lengths", self.lengths))
            _positive(f"arm {name}", values, allow_zero=True)
            object.__setattr__(self, name, None if values == default else values)

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.lengths)

    @property
    def centres(self) -> tuple[float, ...]:
        """Distance of each link's centre of mass from its joint, in metres (``com`` or tips)."""
        return self.lengths if self.com is None else self.com

    @property
    def link_inertias(self) -> tuple[float, ...]:
        """Moment of inertia of each link about its centre of mass, in kg m^2 (zeros if None)."""
        return (0.0,) * self.n_joints if self.inertia is None else self.inertia


@dataclass(frozen=True)
class ElasticJoints:
    """Elastic transmission of the remote arm: ``J theta'' + S (theta - q) = tau``.

    Parameters
    ----------
    stiffness : tuple of float
        Diagonal of the joint stiffness ``S_r`` in N m / rad.
    rotor_inertia : tuple of float
        Diagonal of the motor inertia ``J_r`` in kg m^2.
    """

    stiffness: tuple[float, ...] = (100.0, 100.0)
    rotor_inertia: tuple[float, ...] = (0.3, 0.3)

    def __post_init__(self) -> None:
        _joint_fields(self, {"stiffness": "joint stiffness", "rotor_inertia": "rotor inertia"})
        _positive("joint stiffness", self.stiffness)
        _positive("rotor inertia", self.rotor_inertia)


@dataclass(frozen=True)
class PDGains:
    """Proportional and damping gains of a P+d law, one value per joint.

    Parameters
    ----------
    stiffness : tuple of float
        Proportional gains ``K`` (non-negative).
    damping : tuple of float
        Damping gains ``B`` (non-negative).
    """

    stiffness: tuple[float, ...] = (25.0, 25.0)
    damping: tuple[float, ...] = (10.0, 10.0)

    def __post_init__(self) -> None:
        _joint_fields(self, {"stiffness": "proportional gain", "damping": "damping gain"})
        _positive("proportional gain", self.stiffness, allow_zero=True)
        _positive("damping gain", self.damping, allow_zero=True)

    @classmethod
    def uniform(cls, stiffness: float, damping: float, n_joints: int = 2) -> PDGains:
        """Return the same gains ``(stiffness, damping)`` on every joint.

        Parameters
        ----------
        stiffness : float
            Proportional gain ``K`` of every joint.
        damping : float
            Damping gain ``B`` of every joint.
        n_joints : int
            Number of joints.

        Returns
        -------
        PDGains
            Gains with ``n_joints`` equal entries each.
        """
        return cls((stiffness,) * n_joints, (damping,) * n_joints)

    def as_action(self) -> np.ndarray:
        """Return the gains as the action vector ``[K^1..K^n, B^1..B^n]``."""
        return np.array(self.stiffness + self.damping)


@dataclass(frozen=True)
class Operator:
    """Human operator: a spring-damper pulling the local arm towards a reference motion.

    The operator torque is ``tau_h = K_s (q_h - q_l) - K_d q_l'`` with the reference
    ``q_h,i(t) = G_i A_i sin(w_i t + phi_i) exp(-d_i t)``, where the gains ``G_i`` are drawn per
    episode (see :mod:`teleopkit.sim.scenarios`).

    Parameters
    ----------
    stiffness : float
        Operator stiffness ``K_s`` in N m / rad.
    damping : float
        Operator damping ``K_d`` in N m s / rad.
    amplitudes, frequencies, phases, decays : tuple of float
        Per-joint amplitude (rad), angular frequency (rad/s), phase (rad) and decay rate (1/s) of
        the reference. Zero amplitudes give an operator holding the arm at the origin.
    """

    stiffness: float = 10.0
    damping: float = 2.0
    amplitudes: tuple[float, ...] = (3.0, 2.5)
    frequencies: tuple[float, ...] = (1.0, 1.6)
    phases: tuple[float, ...] = (0.0, 0.05)
    decays: tuple[float, ...] = (0.05, 0.04)

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping"):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"operator {name} must be finite and non-negative, got {value}")
        _joint_fields(self, {name: f"operator {name}"
                             for name in ("amplitudes", "frequencies", "phases", "decays")})

    def reference(self, t: np.ndarray, gains: np.ndarray) -> np.ndarray:
        """Evaluate the reference motion.

        Parameters
        ----------
        t : ndarray, shape (S,)
            Times in seconds.
        gains : ndarray, shape (B, n)
            Per-episode reference gains ``G``.

        Returns
        -------
        ndarray, shape (S, B, n)
            Reference joint angles ``q_h``.
        """
        t = np.asarray(t, dtype=float)[None, :]
        # joints by times, so that the ufuncs run along the long axis
        amplitude, frequency, phase, decay = (np.array(values)[:, None] for values in (
            self.amplitudes, self.frequencies, self.phases, self.decays))
        shape = amplitude * np.sin(frequency * t + phase) * np.exp(-decay * t)
        return np.asarray(gains, dtype=float)[None] * shape.T[:, None, :]


@dataclass(frozen=True)
class Wall:
    """Stiff joint-space wall on the remote arm: a one-sided spring-damper (never pulling).

    Joint ``i`` is in contact when ``q_r,i > position_i``; the environment torque is then
    ``tau_e,i = max(0, stiffness * depth + damping * q_r,i')``.

    Parameters
    ----------
    position : tuple of float
        Wall position per joint in radians (``inf`` for no wall on that joint; ``-inf`` is
        refused: that wall would push at every angle).
    stiffness : float
        Wall stiffness in N m / rad.
    damping : float
        Wall damping in N m s / rad.
    """

    position: tuple[float, ...] = (0.5, math.inf)
    stiffness: float = 1000.0
    damping: float = 5.0

    def __post_init__(self) -> None:
        values = tuple(float(v) for v in self.position)
        if not values or any(math.isnan(v) or v == -math.inf for v in values):
            raise ValueError("wall position must be one number per joint in rad, .inf for no wall "
                             f"on it (-inf would push at every angle), got {values}")
        object.__setattr__(self, "position", values)
        for name in ("stiffness", "damping"):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"wall {name} must be finite and non-negative, got {value}")


@dataclass(frozen=True)
class InitialState:
    """Initial joint positions (velocities start at zero; the past is held constant).

    Parameters
    ----------
    local : tuple of float
        ``q_l(0)`` in radians.
    remote : tuple of float
        ``q_r(0)`` in radians.
    motor : tuple of float
        ``theta_r(0)`` in radians.
    """

    local: tuple[float, ...] = (-0.2, 0.2)
    remote: tuple[float, ...] = (-0.1, 0.1)
    motor: tuple[float, ...] = (0.0, 0.0)

    def __post_init__(self) -> None:
        _joint_fields(self, {n: f"initial {n} position" for n in ("local", "remote", "motor")})


@dataclass(frozen=True)
class TeleoperatorParams:
    """Everything that defines the teleoperator except the delays and the remote gains' schedule.

    Parameters
    ----------
    local_arm : PlanarArm
        Rigid local (master) arm.
    remote_arm : PlanarArm
        Link side of the elastic remote (slave) arm.
    joints : ElasticJoints
        Elastic transmission of the remote arm.
    local_gains : PDGains
        Local P+d gains ``K_l, B_l``.
    remote_gains : PDGains
        Default remote P+d gains ``K_r, B_r`` (the tuner may change them online).
    operator : Operator
        Human operator model.
    environment : {"free"} or Wall
        Free space (``tau_e = 0``) or a stiff wall.
    initial : InitialState
        Initial positions.
    torque_limit : float
        Motor torque saturation in N m (``inf`` disables it).
    """

    local_arm: PlanarArm = field(default_factory=PlanarArm)
    remote_arm: PlanarArm = field(default_factory=PlanarArm)
    joints: ElasticJoints = field(default_factory=ElasticJoints)
    local_gains: PDGains = field(default_factory=PDGains)
    remote_gains: PDGains = field(default_factory=lambda: PDGains((10.0, 10.0), (30.0, 30.0)))
    operator: Operator = field(default_factory=Operator)
    environment: Literal["free"] | Wall = "free"
    initial: InitialState = field(default_factory=InitialState)
    torque_limit: float = 300.0

    def __post_init__(self) -> None:
        n = self.local_arm.n_joints
        sizes = {
            "remote arm": self.remote_arm.n_joints,
            "elastic joints": len(self.joints.stiffness),
            "local gains": len(self.local_gains.stiffness),
            "remote gains": len(self.remote_gains.stiffness),
            "operator reference": len(self.operator.amplitudes),
            "initial state": len(self.initial.local),
        }
        for name, size in sizes.items():
            if size != n:
                raise ValueError(f"{name} has {size} joint{'s' * (size != 1)}, the local arm {n}")
        if isinstance(self.environment, Wall) and len(self.environment.position) != n:
            raise ValueError(f"wall needs {n} positions, got {len(self.environment.position)}")
        if self.environment != "free" and not isinstance(self.environment, Wall):
            raise ValueError(f"environment must be 'free' or a Wall, got {self.environment!r}")
        if math.isnan(self.torque_limit) or self.torque_limit <= 0:
            raise ValueError(f"torque limit must be positive, got {self.torque_limit}")

    @property
    def n_joints(self) -> int:
        """Number of joints of each arm."""
        return self.local_arm.n_joints

    def with_remote_gains(self, stiffness: float, damping: float) -> TeleoperatorParams:
        """Return a copy with uniform remote gains ``K_r = stiffness``, ``B_r = damping``.

        Parameters
        ----------
        stiffness : float
            Remote proportional gain ``K_r`` of every joint.
        damping : float
            Remote damping gain ``B_r`` of every joint.

        Returns
        -------
        TeleoperatorParams
            A copy of these parameters with only ``remote_gains`` replaced.
        """
        return replace(self, remote_gains=PDGains.uniform(stiffness, damping, self.n_joints))


def paper_setup() -> TeleoperatorParams:
    """Return the paper's 2-link teleoperator.

    Returns
    -------
    TeleoperatorParams
        ``l = 0.38 m``, ``m = (0.5, 0.35) kg`` on both arms, ``S_r = 100 I``, ``J_r = 0.3 I``,
        ``K_l = 25``, ``B_l = 10``, ``K_s = 10``, ``K_d = 2``, remote gains ``K_r = 10``,
        ``B_r = 30``, free space, torques saturated at 300 N m.

    Examples
    --------
    >>> params = paper_setup()
    >>> params.n_joints, params.local_gains.stiffness
    (2, (25.0, 25.0))
    """
    return TeleoperatorParams()


def one_joint_setup() -> TeleoperatorParams:
    """The paper's first joint alone (same link, spring, rotor, gains and operator).

    Returns
    -------
    TeleoperatorParams
        A one-joint teleoperator, small enough for LMI certificates in seconds.
    """
    arm = PlanarArm((0.38,), (0.5,))
    return TeleoperatorParams(
        local_arm=arm, remote_arm=arm, joints=ElasticJoints((100.0,), (0.3,)),
        local_gains=PDGains((25.0,), (10.0,)), remote_gains=PDGains((10.0,), (30.0,)),
        operator=Operator(amplitudes=(3.0,), frequencies=(1.0,), phases=(0.0,),
                          decays=(0.05,)),
        initial=InitialState((-0.2,), (-0.1,), (0.0,)))
