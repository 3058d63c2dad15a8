"""A gain law that plays its start, for the tests of moving laws between certificates."""

from __future__ import annotations

import numpy as np

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.rl.features import observation_size
from teleopkit.rl.policy import GainPolicy
from teleopkit.safety.factory import layer_for


def still_law(start: np.ndarray, certificate: GainCertificate) -> GainPolicy:
    """A law with zero weights (it plays ``start``), searched under ``certificate``."""
    low = np.asarray(certificate.box.lower, dtype=float)
    width = (observation_size("adaptive", certificate.box.n_joints)
             + layer_for(certificate).run_time_state(1).shape[1])
    metadata = {"law_search": {}, "certificate": certificate.to_dict(), "start": start.tolist(),
                "observation": "adaptive"}
    return GainPolicy([(np.zeros((low.size, width)), np.zeros(low.size))], np.zeros(width),
                      np.ones(width), low, (start - low) / np.log(2.0), metadata)
