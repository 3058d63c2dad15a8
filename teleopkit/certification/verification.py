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
from typing import Any

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.methods import certify_with
from teleopkit.certification.question import Question
from teleopkit.model.params import plant_params

__all__ = ["check_certificate", "load_certificate", "verify_certificate"]


def _plain(data: Any) -> Any:
    """``data`` as JSON reads it back (tuples become lists)."""
    return json.loads(json.dumps(data, default=dict))  # read-only views as the dicts they show


def _check_closed_form(certificate: GainCertificate) -> None:
    """Raise unless the closed form re-derives exactly what the certificate states."""
    derived = certify_with("nuno", Question(plant_params(certificate.plant), certificate.box,
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
        _check_closed_form(certificate)
        return
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


def load_certificate(text: str) -> GainCertificate:
    """Parse a certificate's JSON and re-check it: the way to read one for use.

    Parameters
    ----------
    text : str
        JSON as :meth:`~teleopkit.certification.gain_certificate.GainCertificate.to_json`
        writes it.

    Returns
    -------
    GainCertificate
        The certificate, checked.

    Raises
    ------
    ValueError
        One line: malformed text, or a certificate that does not check out (edited, or for a
        plant its record does not match).
    """
    certificate = GainCertificate.from_json(text)
    check_certificate(certificate)
    return certificate
