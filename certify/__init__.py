"""Stability certificates for linear time-delay systems.

Generic, robot-free mathematics of ``E x' = A0 x + sum_i A_i x(t - tau_i(t))``:

* delay-dependent LMI certificates (Lyapunov–Krasovskii with Jensen, reciprocally convex
  and Wirtinger bounds, and a scaled small-gain test) for constant, slowly varying or
  fast-varying delays, for single systems and for polytopes of systems (parameter switching
  arbitrarily fast, or frozen), with affine parameters handled by full-block multipliers
  instead of vertex enumeration (varying arbitrarily fast, at a bounded rate, or constant),
  as re-checkable, JSON-serialisable certificates;
* exact constant-delay spectra (rightmost characteristic roots) and delay margins.
"""

from certify.bisection import certify_delay, max_delay, max_delay_certificate
from certify.certificate import Certificate
from certify.methods import METHODS
from certify.spectrum import (
    exact_constant_margin,
    rightmost_roots,
    spectral_abscissa,
    stability_intervals,
)
from certify.system import LinearDelaySystem, PolytopicDelaySystem
from certify.uncertainty import AffineUncertainty, Direction

__all__ = [
    "METHODS",
    "AffineUncertainty",
    "Certificate",
    "Direction",
    "LinearDelaySystem",
    "PolytopicDelaySystem",
    "certify_delay",
    "exact_constant_margin",
    "max_delay",
    "max_delay_certificate",
    "rightmost_roots",
    "spectral_abscissa",
    "stability_intervals",
]
