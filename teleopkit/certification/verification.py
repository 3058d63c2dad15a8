"""Re-checking a certificate read from a file: nothing unverified reaches the plant.

A closed-form certificate (frozen, ``scheduled:L`` or ``tank``) is re-derived from the plant,
box, delay bounds and class it records, and must agree with what it states; an LMI certificate's
stored solutions must satisfy their LMIs again and certify the polytope it offers.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.model.params import plant_params

__all__ = ["verify_certificate"]


def _plain(data: Any) -> Any:
    """``data`` as JSON reads it back (tuples become lists)."""
    return json.loads(json.dumps(data))


def _derived(certificate: GainCertificate) -> GainCertificate:
    from teleopkit.certification.certifier import certify_gains

    return certify_gains(plant_params(certificate.plant), certificate.box,
                         *certificate.delay_bounds, method="nuno",
                         variation=certificate.gain_variation)


def verify_certificate(certificate: GainCertificate) -> None:
    """Raise unless the certificate is what its method derives from what it records.

    Parameters
    ----------
    certificate : GainCertificate
        A certificate, typically read with :meth:`GainCertificate.from_json`.

    Raises
    ------
    ValueError
        One line naming what does not check out.
    """
    if not certificate.plant:
        raise ValueError("the certificate names no plant; certify again with this teleopkit")
    if certificate.method not in ("nuno", "lmi"):
        raise ValueError(f"unknown certificate method {certificate.method!r}")
    if certificate.method == "lmi":
        from teleopkit.certification.lmi.verdict import verify_lmi

        verify_lmi(certificate)
        return
    derived = _derived(certificate)
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
