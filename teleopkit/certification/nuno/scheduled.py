"""Certificates of the scheduled gain classes (``scheduled:L``, ``tank``) on the nonlinear plant.

The remote stiffness has the local gains' shape, ``K_r = kappa S`` (``S = K_l / K_l^1``); the
damping lies in the cone ``B_r^i >= rho_i K_r^i`` of the closed form; ``kappa`` rises freely and
falls within a log budget ``L`` per episode (``scheduled:L``) or as an energy tank allows
(``tank``). The proof is the storage of :mod:`teleopkit.certification.nuno.lyapunov`:
``V(t) <= exp(L) V(0)``, or ``V(t) + tank(t) <= V(0) + T0``. The certified set is the closed-form
polytope of the box restricted to the common shape; the run-time part of the class (budget or
tank) is enforced by the safety layer at every control step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.nuno.condition import NUNO_EPS, nuno_joint_margins, nuno_polytope
from teleopkit.certification.nuno.guarantee import Start, resolve_tank
from teleopkit.certification.nuno.lyapunov import ScheduledStorage
from teleopkit.certification.scheduled_set import ScheduledSet
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.plant_range import PlantRange
from teleopkit.model.records import plant_record

__all__ = ["TANK_REFILL", "certify_scheduled", "plants_tank", "scheduled_set", "shape_rows"]

TANK_REFILL = 0.5
"""Fraction of the proven dissipation that refills the tank (and of the storage released when
``kappa`` rises). Below 1, ``V + tank`` falls by the rest, which keeps the velocities square
integrable; at 1 it would only stay bounded."""

_COMMON = (
    "nonlinear teleoperator with elastic remote joints (no linearisation)",
    "passive operator and environment (torque-controlled arms, no torque saturation)",
    "time-varying delays 0 <= T_i(t) <= T_i*, derivative unrestricted",
    "remote gains held between control samples",
)


def scheduled_set(params: TeleoperatorParams, storage: ScheduledStorage, box: GainBox,
                  variation: GainVariation) -> ScheduledSet:
    """The set a scheduled class allows inside a box: common shape, box and the closed form's cone.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (its local damping gives the cone's offset).
    storage : ScheduledStorage
        Shape and cone of the plant and delay bounds.
    box : GainBox
        Remote gain ranges.
    variation : GainVariation
        ``scheduled:L`` or ``tank[:T0]``.

    Returns
    -------
    ScheduledSet
        The set: the closed form's row ``4 B_l B_r >= (T_l* + T_r*)^2 K_l K_r + eps`` is the cone
        ``B_r >= rho K_r + eps / (4 B_l)``; empty when no common-shape stiffness of the box lies
        in it.
    """
    n = box.n_joints
    shape, cone = np.array(storage.shape), np.array(storage.cone)
    offset = NUNO_EPS / (4 * np.array(params.local_gains.damping))
    high = box.upper[n:]
    kappa_high = np.minimum(box.upper[:n] / shape, (high - offset) / (cone * shape))
    tank = variation.kind == "tank"
    return ScheduledSet(tuple(shape.tolist()), tuple(cone.tolist()), tuple(offset.tolist()),
                        tuple(box.lower[n:].tolist()), tuple(high.tolist()),
                        float(np.max(box.lower[:n] / shape)), float(np.min(kappa_high)),
                        "tank" if tank else "budget", float(variation.value),
                        TANK_REFILL if tank else 0.0)


def shape_rows(shape: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The rows ``K_r^i = s_i K_r^1`` (two inequalities each) as ``(G, h, labels)``.

    Parameters
    ----------
    shape : tuple of float
        ``s_i``.

    Returns
    -------
    tuple
        Normals ``(2 (n - 1), 2 n)``, zero offsets and labels.
    """
    n = len(shape)
    rows, labels = [], []
    for i in range(1, n):
        row = np.zeros(2 * n)
        row[i], row[0] = 1.0, -shape[i] / shape[0]
        rows += [row, -row]
        labels += [f"common shape: K_r{i + 1} <= {shape[i]:g} K_r1",
                   f"common shape: K_r{i + 1} >= {shape[i]:g} K_r1"]
    return np.array(rows).reshape(-1, 2 * n), np.zeros(len(rows)), tuple(labels)


def plants_tank(plants: Sequence[TeleoperatorParams], box: GainBox, tl_max: float,
                tr_max: float, variation: GainVariation | str,
                ranges: Sequence[PlantRange] = (), start: Start | None = None,
                ) -> GainVariation:
    """The class, with a tank asked for in ``rad`` sized for every plant, range and start.

    ``tank:Drad`` is the tank whose bound allows ``D`` rad of spring deflection on the first
    plant from its start; certifying several plants, or a plant's ranges, or from starts drawn
    from ranges (or several starts), takes the smallest level over them
    (:func:`~teleopkit.certification.nuno.guarantee.resolve_tank`), which the certificate of
    the first plant then carries as ``tank:T0``.

    Parameters
    ----------
    plants : sequence of TeleoperatorParams
        The plants (at least one; one closed-form storage serves them all).
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : GainVariation or str
        The class; returned parsed, and unchanged unless it is a tank given in ``rad``.
    ranges : sequence of PlantRange, optional
        The range of each plant; none by default.
    start : StartSpec or StartMix, optional
        Initial positions, fixed or ranges (a setup's start); each plant's ``initial`` by
        default.

    Returns
    -------
    GainVariation
        The class.
    """
    variation = (variation if isinstance(variation, GainVariation)
                 else parse_gain_variation(variation))
    if variation.unit != "rad":
        return variation
    storage = ScheduledStorage.for_plant(plants[0], tl_max, tr_max)
    allowed = scheduled_set(plants[0], storage, box, variation)
    return resolve_tank(plants, storage, allowed, variation, ranges, start)


def certify_scheduled(params: TeleoperatorParams, box: GainBox, tl_max: float, tr_max: float,
                      variation: GainVariation) -> GainCertificate:
    """The certificate of a gain box for a scheduled class.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator (positive local gains).
    box : GainBox
        Remote gain ranges.
    tl_max, tr_max : float
        Delay bounds in seconds.
    variation : GainVariation
        ``scheduled:L`` or ``tank[:T0]``.

    Returns
    -------
    GainCertificate
        Certified when every common-shape gain of the box lies in the cone; the polytope is the
        box restricted to the common shape and the cone, and ``details`` holds the storage.
    """
    if not variation.scheduled:
        raise ValueError(f"certify_scheduled covers scheduled:L and tank, not {variation}")
    storage = ScheduledStorage.for_plant(params, tl_max, tr_max)
    variation = resolve_tank(params, storage, scheduled_set(params, storage, box, variation),
                             variation)
    allowed = scheduled_set(params, storage, box, variation)
    n = box.n_joints
    box_high = float(np.min(box.upper[:n] / np.array(storage.shape)))
    polytope = nuno_polytope(params, box, tl_max, tr_max).intersect(*shape_rows(storage.shape))
    worst = np.concatenate([box_high * np.array(storage.shape), box.lower[n:]])
    margins = nuno_joint_margins(params, worst)
    in_cone = box.lower[n:] >= np.array(storage.cone) * worst[:n]
    certified = bool(allowed.kappa_low <= box_high and np.all(in_cone))
    violation = None
    if allowed.kappa_low > box_high:
        violation = "no common-shape stiffness K_r = kappa K_l / K_l^1 lies in the box"
    elif not certified:
        i = int(np.argmin(in_cone))
        violation = (f"joint {i + 1} at kappa = {box_high:g}, B_r = {box.lower[n + i]:g}: "
                     f"below the cone B_r >= {storage.cone[i]:g} K_r")
    guarantee = (f"guarantee: the storage V of teleopkit.certification.nuno.lyapunov obeys V(t) <= "
                 f"exp({variation.value:g}) V(0)" if variation.kind == "scheduled" else
                 "guarantee: V(t) + tank(t) <= V(0) + T0 for the storage V of "
                 "teleopkit.certification.nuno.lyapunov (falls of kappa paid from the measured "
                 "remote energy)")
    details = {"storage": asdict(storage), "set": allowed.to_dict()}
    return GainCertificate(certified, "nuno", str(variation), (tl_max, tr_max),
                           float(margins.min()), box, polytope, not allowed.is_empty,
                           (*_COMMON, guarantee), violation, details,
                           plant_record(params))
