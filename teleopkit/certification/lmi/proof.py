"""LMI proofs a certificate file carries, and their re-check from the plant alone.

An LMI certificate of a gain set is one LMI solution, or a cover: cells (the set clipped to boxes
of a recursive split of its bounding box), each with its own solution. Its proof records, per
cell, the box and what :class:`certify.Certificate` needs to re-check the LMIs (decision
matrices, channel maps, state scaling), and the boxes of the split that miss the set. It does
not record the linear systems: :func:`check_proof` rebuilds them from the plant, the set and
the boxes, so an edited plant, set, bound or matrix cannot pass.

That the cells cover the set is checked too: the boxes lie in the box that was split (the set's
bounding box, or a recorded ``root`` that contains it), their interiors are disjoint and their
volumes add up to its volume, so (being closed) they tile it, and the set is the union of its
clippings.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from certify import Certificate
from teleopkit.certification.gain_sets import GainPolytope, box_within
from teleopkit.certification.lmi.cover import Cover
from teleopkit.certification.lmi.planner import clip
from teleopkit.certification.lmi.systems import NO_LOWER, gain_set_system
from teleopkit.model.params import TeleoperatorParams

__all__ = ["certificate_proof", "check_proof", "cover_proof"]

_VOLUME_RTOL = 1e-9


def cover_proof(cover: Cover, bounds: Sequence[float],
                delay_lower: Sequence[float] = NO_LOWER) -> dict[str, Any]:
    """The JSON-ready proof of a certified cover.

    Parameters
    ----------
    cover : Cover
        A certified cover (:func:`~teleopkit.certification.lmi.cover.set_certificate`).
    bounds : sequence of float
        The delay bounds ``(T_l*, T_r*)`` it was certified for.
    delay_lower : sequence of float
        The lower delay bounds ``(T_l_min, T_r_min)`` it was certified for.

    Returns
    -------
    dict
        ``bounds``, ``lower``, ``variation``, ``cells`` (box, LMI data), ``empty`` boxes and,
        when the split started from a box larger than the set's bounding box, that ``root``.
    """
    if not cover.certified:
        raise ValueError("only a certified cover has a proof")
    cells = [{"box": None if box is None else [box[0].tolist(), box[1].tolist()],
              "lmi": _lmi_data(cert)}
             for box, cert in zip(cover.boxes, cover.certificates, strict=True)]
    proof = {"bounds": [float(b) for b in bounds], "lower": [float(b) for b in delay_lower],
             "variation": cover.variation, "cells": cells,
             "empty": [[low.tolist(), high.tolist()] for low, high in cover.empty]}
    if cover.root is not None:
        proof["root"] = [cover.root[0].tolist(), cover.root[1].tolist()]
    return proof


def certificate_proof(cert: Certificate, variation: str) -> dict[str, Any]:
    """The proof of one LMI solution for a whole gain set (the format of :func:`cover_proof`).

    Parameters
    ----------
    cert : certify.Certificate
        A certified solution for the set's system.
    variation : str
        The gain class the set's system was built for.

    Returns
    -------
    dict
        A one-cell proof.
    """
    if not cert.certified:
        raise ValueError("only a certified solution has a proof")
    return {"bounds": list(cert.delay_bounds), "lower": list(_lower_of(cert)),
            "variation": variation, "cells": [{"box": None, "lmi": _lmi_data(cert)}],
            "empty": []}


def _lower_of(cert: Certificate) -> tuple[float, ...]:
    """The lower delay bounds of a solution (zeros when it records none)."""
    return tuple(cert.delay_lower) or (0.0,) * len(cert.delay_bounds)


def _lmi_data(cert: Certificate) -> dict[str, Any]:
    """What re-checks an LMI solution once its system is rebuilt."""
    data = cert.to_dict()
    return {key: data[key] for key in ("method", "delay_bounds", "delay_lower", "mu",
                                       "matrices", "channels", "scaling", "eliminated")}


def check_proof(params: TeleoperatorParams, polytope: GainPolytope, proof: Mapping[str, Any],
                 bounds: Sequence[float], variations: Sequence[str],
                 delay_lower: Sequence[float] = NO_LOWER) -> None:
    """Raise unless ``proof`` certifies ``polytope`` for delays in ``[delay_lower, bounds]``.

    Parameters
    ----------
    params : TeleoperatorParams
        The plant the certificate names.
    polytope : GainPolytope
        The gain set it certifies.
    proof : Mapping
        As written by :func:`cover_proof`.
    bounds : sequence of float
        Delay bounds ``(T_l*, T_r*)`` the proof must cover (it may be for larger ones).
    variations : sequence of str
        Gain classes of the cells that cover the claim (``"switching"`` covers ``"frozen"``).
    delay_lower : sequence of float
        Lower delay bounds the proof must cover (it may be for smaller ones).

    Raises
    ------
    ValueError
        One line naming what fails.
    """
    try:
        cells, empty = list(proof["cells"]), list(proof["empty"])
        variation, proved = str(proof["variation"]), [float(b) for b in proof["bounds"]]
        floors = [float(b) for b in proof.get("lower", [0.0] * len(proved))]
    except (KeyError, TypeError, ValueError):
        raise ValueError("the certificate's LMI proof is malformed") from None
    if variation not in variations:
        raise ValueError(f"the certificate's LMI proof is for {variation} gains, which does not "
                         f"cover {' or '.join(variations)}")
    if len(proved) != len(bounds) or any(p < b * (1 - 1e-12) for p, b in zip(proved, bounds,
                                                                               strict=True)):
        raise ValueError(f"the certificate's LMI proof is for delay bounds {proved}, which do not "
                         f"cover {list(bounds)}")
    if len(floors) != len(proved) or any(f > low * (1 + 1e-12) for f, low in zip(
            floors, delay_lower, strict=True)):
        raise ValueError(f"the certificate's LMI proof is for delays from {floors} s, which does "
                         f"not cover delays from {list(delay_lower)} s")
    if not cells:
        raise ValueError("the certificate's LMI proof has no cell")
    boxes = [_box(cell.get("box")) for cell in cells]
    if any(box is None for box in boxes):
        if len(cells) != 1 or empty:
            raise ValueError("the certificate's LMI proof mixes the whole set with cells")
    else:
        _check_tiling(polytope, [b for b in boxes if b is not None], [_box(b) for b in empty],
                      _box(proof.get("root")))
    for index, (cell, box) in enumerate(zip(cells, boxes, strict=True)):
        region = polytope if box is None else clip(polytope, box)
        if not _solution_holds(params, region, variation, cell.get("lmi"), proved, floors):
            raise ValueError(f"the LMI solution of cell {index} of the certificate's proof does "
                             "not hold for its plant and gains (edited?)")


def _box(data: Any) -> tuple[np.ndarray, np.ndarray] | None:
    if data is None:
        return None
    try:
        low, high = (np.asarray(x, dtype=float) for x in data)
    except (TypeError, ValueError):
        raise ValueError("the certificate's LMI proof has a malformed box") from None
    if low.shape != high.shape or low.ndim != 1 or not np.all(np.isfinite([low, high])):
        raise ValueError("the certificate's LMI proof has a malformed box")
    return low, high


def _check_tiling(polytope: GainPolytope, cells: list[tuple[np.ndarray, np.ndarray]],
                  empty: list[tuple[np.ndarray, np.ndarray] | None],
                  root: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """The boxes tile a root box that contains the set, and the empty ones miss the set.

    The root is by default the set's bounding box.
    """
    corners = polytope.vertices()
    if corners.size == 0:
        raise ValueError("the certificate's gain polytope is empty")
    low, high = corners.min(axis=0), corners.max(axis=0)
    if root is not None:
        if root[0].shape != low.shape or not box_within((low, high), root):
            raise ValueError("the root box of the certificate's LMI proof does not contain its "
                             "gain set")
        low, high = root
    boxes = cells + [b for b in empty if b is not None]
    wide = high - low > 1e-12 * np.maximum(1.0, np.abs(high))

    def volume(box: tuple[np.ndarray, np.ndarray]) -> float:
        return float(np.prod((box[1] - box[0])[wide]))

    for b_low, b_high in boxes:
        if (b_low.shape != low.shape or np.any(b_high < b_low)
                or np.any(b_low < low - 1e-9 * np.abs(low))
                or np.any(b_high > high + 1e-9 * np.abs(high))):
            raise ValueError("a box of the certificate's LMI proof leaves the gain set's bounds")
    for (a_low, a_high), (b_low, b_high) in itertools.combinations(boxes, 2):
        overlap = np.minimum(a_high, b_high) - np.maximum(a_low, b_low)
        if np.all(overlap[wide] > 1e-12 * np.maximum(1.0, np.abs(a_high[wide]))):
            raise ValueError("two boxes of the certificate's LMI proof overlap")
    total = sum(volume(b) for b in boxes)
    if not np.isclose(total, volume((low, high)), rtol=_VOLUME_RTOL, atol=0):
        raise ValueError("the cells of the certificate's LMI proof do not cover its gain set")
    for box in empty:
        if box is None or not clip(polytope, box).is_empty():
            raise ValueError("a box the certificate's LMI proof calls empty meets the gain set")


def _solution_holds(params: TeleoperatorParams, region: GainPolytope, variation: str,
                    data: Any, bounds: Sequence[float], floors: Sequence[float]) -> bool:
    """Whether the stored solution satisfies the LMIs of the rebuilt system of ``region``."""
    if not isinstance(data, Mapping) or region.is_empty():
        return False
    try:
        system = gain_set_system(params, region, variation)
        cert = Certificate(
            certified=True, method=str(data["method"]),
            delay_bounds=tuple(float(x) for x in data["delay_bounds"]),
            mu=None if data["mu"] is None else float(data["mu"]), assumptions=(), system=system,
            matrices={str(k): np.asarray(v, dtype=float) for k, v in data["matrices"].items()},
            channels=tuple(np.asarray(c, dtype=float).reshape(-1, system.n)
                           for c in data["channels"]),
            scaling=tuple(float(x) for x in data["scaling"]),
            delay_lower=tuple(float(x) for x in data["delay_lower"]),
            eliminated=tuple(int(x) for x in data.get("eliminated", ())))
    except (KeyError, TypeError, ValueError, AttributeError):
        return False
    return bool(np.array_equal(cert.delay_bounds, bounds)
                and np.array_equal(_lower_of(cert), floors) and cert.verify())
