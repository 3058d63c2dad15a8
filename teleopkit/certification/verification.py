"""Re-checking a certificate: nothing unverified reaches the plant.

A closed-form certificate (frozen, ``scheduled:L`` or ``tank``) is re-derived from the plant,
box, delay bounds and class it records, and must agree with what it states; an LMI certificate's
stored solutions must satisfy their LMIs again and certify the polytope it offers.

One contract, as in :meth:`certify.Certificate.verify`: *verify* answers with a bool and never
raises on a bad certificate (:func:`verify_certificate`); *check* raises a one-line
:class:`ValueError` naming what does not hold (:func:`check_certificate`, like
:meth:`~teleopkit.certification.gain_certificate.GainCertificate.check` for the plant and the
delays); :func:`load_certificate` parses JSON and checks it, which is how a certificate read from
a file is used.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.methods import certify_with
from teleopkit.certification.question import Question
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.plant_range import PlantRange
from teleopkit.model.records import plant_params, plant_record

__all__ = ["check_certificate", "cover_plants", "load_certificate", "verify_certificate"]

_ONE_PLANT = ("an LMI certificate is for one plant; certify several with the closed form "
              "(method nuno)")


def _plain(data: Any) -> Any:
    """``data`` as JSON reads it back (tuples become lists)."""
    return json.loads(json.dumps(data, default=dict))  # read-only views as the dicts they show


def _check_closed_form(certificate: GainCertificate,
                       plant: Mapping[str, Any] | None = None) -> None:
    """Raise unless the closed form re-derives exactly what the certificate states.

    For ``plant`` (one of its :attr:`~GainCertificate.other_plants`) in place of its first.
    """
    record = certificate.plant if plant is None else plant
    derived = certify_with("nuno", Question(plant_params(record), certificate.box,
                                            certificate.delay_bounds,
                                            variation=certificate.variation))
    for name in ("certified", "polytope_certified", "delay_lower", "assumptions"):
        if getattr(derived, name) != getattr(certificate, name):
            raise ValueError(f"the certificate states {name} = {getattr(certificate, name)}, "
                             f"its plant and box give {getattr(derived, name)}")
    if not certificate.polytope.same_as(derived.polytope):
        raise ValueError("the certificate's gain polytope is not the one its plant, box and "
                         "delay bounds give (edited?)")
    if not np.isclose(derived.delay_margin, certificate.delay_margin, rtol=1e-12):
        raise ValueError(f"the certificate states a delay margin of {certificate.delay_margin:g} "
                         f"s, its plant and box give {derived.delay_margin:g} s")
    if _plain(derived.details) != _plain(certificate.details):
        raise ValueError("the certificate's details (storage, cone) are not those its plant and "
                         "box give")


def check_certificate(certificate: GainCertificate) -> None:
    """Raise unless the certificate is what its method derives from what it records.

    Parameters
    ----------
    certificate : GainCertificate
        A certificate, for example parsed with
        :meth:`~teleopkit.certification.gain_certificate.GainCertificate.from_json`.

    Raises
    ------
    ValueError
        One line naming what does not check out.
    """
    if not certificate.plant:
        raise ValueError("the certificate names no plant; certify again with this teleopkit")
    if certificate.method not in ("nuno", "lmi"):
        raise ValueError(f"unknown certificate method {certificate.method!r}")
    if certificate.method == "nuno":
        for record, interval in zip((certificate.plant, *certificate.other_plants),
                                    certificate.ranges, strict=True):
            for plant in _checked_plants(record, interval):
                _check_closed_form(certificate, plant)
        return
    if certificate.other_plants or certificate.plant_ranges:
        raise ValueError(_ONE_PLANT)
    from teleopkit.certification.lmi.verdict import check_lmi  # cvxpy: only when asked for

    check_lmi(certificate)


def verify_certificate(certificate: GainCertificate) -> bool:
    """Whether the certificate re-checks (:func:`check_certificate` without the reason).

    Parameters
    ----------
    certificate : GainCertificate
        A certificate.

    Returns
    -------
    bool
        True when every check holds; never raises on a bad certificate.
    """
    try:
        check_certificate(certificate)
    except ValueError:
        return False
    return True


def load_certificate(text: str | os.PathLike[str]) -> GainCertificate:
    """Parse a certificate's JSON and re-check it: the way to read one for use.

    Parameters
    ----------
    text : str or path-like
        JSON as :meth:`~teleopkit.certification.gain_certificate.GainCertificate.to_json`
        writes it, or the path of a file holding it
        (:meth:`~teleopkit.certification.gain_certificate.GainCertificate.from_json`).

    Returns
    -------
    GainCertificate
        The certificate, checked.

    Raises
    ------
    ValueError
        One line: malformed text, a missing file, or a certificate that does not check out
        (edited, or for a plant its record does not match).
    """
    certificate = GainCertificate.from_json(text)
    check_certificate(certificate)
    return certificate


def _checked_plants(record: Mapping[str, Any], interval: PlantRange) -> list[dict[str, Any]]:
    """The plant records a closed form is derived again for: the plant, and its range's ends."""
    if not interval:
        return [dict(record)]
    return [dict(record), *(plant_record(end) for end in interval.corners(plant_params(record)))]


def cover_plants(certificate: GainCertificate, plants: Sequence[TeleoperatorParams],
                 ranges: Sequence[PlantRange] = ()) -> GainCertificate:
    """The certificate extended to every plant of ``plants``, where its verdict holds for each.

    The closed form's set depends on the plant only through the local gains ``K_l, B_l`` (its
    storage holds for any elastic-joint arms, passive operator and environment): derived again
    for each further plant (and for both ends of its range), it must give the same verdict, set
    and details, else the plants need certificates of their own.

    Parameters
    ----------
    certificate : GainCertificate
        A closed-form certificate (method ``"nuno"``) for one of the plants.
    plants : sequence of TeleoperatorParams
        The plants to cover (for example :attr:`teleopkit.setup.Setup.plants`).
    ranges : sequence of PlantRange, optional
        The range of each plant (:attr:`teleopkit.setup.Setup.ranges`); none by default.

    Returns
    -------
    GainCertificate
        ``certificate`` itself when it covers them already, else a copy recording the others
        in :attr:`~GainCertificate.other_plants`.

    Raises
    ------
    ValueError
        One line: an LMI certificate for several plants, or a plant the set differs for.
    """
    ranges = tuple(ranges) or (PlantRange(),) * len(plants)
    missing = [(params, interval) for params, interval in zip(plants, ranges, strict=True)
               if not all(certificate.covers_plant(end) for end in
                          (params, *interval.corners(params)))]
    if not missing:
        return certificate
    if certificate.method != "nuno":
        raise ValueError(_ONE_PLANT)
    records = [dict(record) for record in (certificate.plant, *certificate.other_plants)]
    intervals = list(certificate.ranges)
    added = []
    for params, interval in missing:
        record = plant_record(params)
        same = [k for k, known in enumerate(records)
                if known.get("fingerprint") == record["fingerprint"] and not intervals[k]]
        if same:  # a recorded plant gets its range
            intervals[same[0]] = interval
        else:
            records.append(record)
            intervals.append(interval)
        added.append((record, interval))
    extended = replace(certificate, other_plants=tuple(records[1:]),
                       plant_ranges=tuple(interval.to_record() for interval in intervals))
    for record, interval in added:
        try:
            for plant in _checked_plants(record, interval):
                _check_closed_form(extended, plant)
        except ValueError:
            raise ValueError("the closed form certifies another set for one of the plants (its "
                             "local gains differ): certify each plant on its own") from None
    return extended
