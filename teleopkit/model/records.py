"""Plant records: what a stability certificate depends on, as JSON-ready data, and back.

A certificate file records the plant it was proved for (:func:`plant_record`, with a
fingerprint); :func:`plant_mismatch` says in one line how a plant in use differs from it, and
:func:`plant_params` rebuilds the teleoperator from a record.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import asdict
from typing import Any

from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    Wall,
)

__all__ = ["PLANT_LABELS", "json_ready", "plant_mismatch", "plant_params", "plant_record"]


PLANT_LABELS: dict[str, str] = {
    "local_arm.lengths": "local arm lengths", "local_arm.masses": "local arm masses",
    "remote_arm.lengths": "remote arm lengths", "remote_arm.masses": "remote arm masses",
    "local_arm.com": "local arm centres of mass", "local_arm.inertia": "local arm link inertias",
    "remote_arm.com": "remote arm centres of mass",
    "remote_arm.inertia": "remote arm link inertias",
    "joints.stiffness": "joint stiffness S_r", "joints.rotor_inertia": "rotor inertia J_r",
    "local_gains.stiffness": "K_l", "local_gains.damping": "B_l",
    "operator.stiffness": "operator stiffness K_s", "operator.damping": "operator damping K_d",
    "environment": "environment",
}
"""What a plant record's entries (``part.field``) are called in messages."""


def json_ready(value: Any) -> Any:
    """JSON-safe data: tuples as lists, infinite floats as the strings ``"inf"``, ``"-inf"``.

    Parameters
    ----------
    value : object
        Nested dicts, lists, tuples and scalars.

    Returns
    -------
    object
        The same structure, JSON-ready.
    """
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return "inf" if value > 0 else "-inf"
    return value


def _arm_record(arm: PlanarArm) -> dict[str, Any]:
    """The arm's fields without those left at their point-mass default (``com``, ``inertia``)."""
    return {key: value for key, value in asdict(arm).items() if value is not None}


def plant_record(params: TeleoperatorParams) -> dict[str, Any]:
    """What a stability certificate depends on, as plain JSON-ready data, with a fingerprint.

    The plant is everything of ``params`` but the default remote gains (the tuner sets them),
    the initial state, the operator's reference motion and the torque limit: none of them
    enters a stability proof (every certificate assumes torques below saturation).

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.

    Returns
    -------
    dict
        ``local_arm``, ``remote_arm`` (``com`` and ``inertia`` only where they are not None, so
        that the record of point masses is the one from before these fields existed),
        ``joints``, ``local_gains``, ``operator`` (stiffness and damping), ``environment`` and
        ``fingerprint`` (SHA-256 of the rest, 16 hex digits).
    """
    record = {
        "local_arm": _arm_record(params.local_arm), "remote_arm": _arm_record(params.remote_arm),
        "joints": asdict(params.joints), "local_gains": asdict(params.local_gains),
        "operator": {"stiffness": params.operator.stiffness,
                     "damping": params.operator.damping},
        "environment": (asdict(params.environment) if isinstance(params.environment, Wall)
                        else params.environment),
    }
    record = json_ready(record)
    digest = hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()[:16]
    return {**record, "fingerprint": digest}


def _flatten(record: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in record.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping) and name != "environment":
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def plant_mismatch(certified: Mapping[str, Any], params: TeleoperatorParams) -> str | None:
    """How a certificate's plant record differs from ``params`` (None when they agree).

    Parameters
    ----------
    certified : mapping
        A :func:`plant_record`, for example read from a certificate file.
    params : TeleoperatorParams
        The plant in use.

    Returns
    -------
    str or None
        One line naming the first differing quantity and both values.
    """
    actual = plant_record(params)
    if certified.get("fingerprint") == actual["fingerprint"]:
        return None
    mine, theirs = _flatten(actual), _flatten(certified)
    for name, value in mine.items():
        if name != "fingerprint" and theirs.get(name) != value:
            label = PLANT_LABELS.get(name, name)
            return (f"the certificate is for {label} = {theirs.get(name)}, the plant has "
                    f"{value}")
    return "the certificate's plant fingerprint does not match its recorded plant"


def _floats(value: Any) -> Any:
    """Inverse of :func:`json_ready` on numbers: ``"inf"`` back to a float."""
    if isinstance(value, dict):
        return {key: _floats(item) for key, item in value.items()}
    if isinstance(value, list):
        return tuple(_floats(item) for item in value)
    if value in ("inf", "-inf"):
        return float(value)
    return value


def plant_params(record: Mapping[str, Any]) -> TeleoperatorParams:
    """The teleoperator of a :func:`plant_record` (defaults for what the record leaves out).

    Parameters
    ----------
    record : mapping
        A plant record, for example read from a certificate file.

    Returns
    -------
    TeleoperatorParams
        Arms (masses at the link tips and no link inertia where the record has no ``com`` or
        ``inertia``), joints, local gains, operator spring and damper and environment of the
        record; remote gains ``K_r = 10, B_r = 30``, the operator holding the origin, every
        position starting at zero and no torque saturation.

    Raises
    ------
    ValueError
        If the record is malformed.
    """
    try:
        data = _floats({key: value for key, value in record.items() if key != "fingerprint"})
        environment = data["environment"]
        n = len(data["local_arm"]["lengths"])
        zeros = (0.0,) * n
        return TeleoperatorParams(
            local_arm=PlanarArm(**data["local_arm"]), remote_arm=PlanarArm(**data["remote_arm"]),
            joints=ElasticJoints(**data["joints"]), local_gains=PDGains(**data["local_gains"]),
            remote_gains=PDGains.uniform(10.0, 30.0, n),
            operator=Operator(**data["operator"], amplitudes=zeros, frequencies=zeros,
                              phases=zeros, decays=zeros),
            environment=environment if environment == "free" else Wall(**environment),
            initial=InitialState(zeros, zeros, zeros), torque_limit=math.inf)
    except (KeyError, TypeError, AttributeError) as error:
        raise ValueError(f"malformed plant record: {error}") from None
