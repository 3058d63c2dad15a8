"""Exact constant-delay spectra: rightmost characteristic roots and delay margins.

Roots of ``det(lambda E - A0 - sum_i A_i exp(-lambda tau_i)) = 0`` are approximated by the
eigenvalues of a Chebyshev collocation of the infinitesimal generator (Breda, Maset &
Vermiglio 2005), refined by Newton's method on the characteristic equation, with the
number of nodes doubled until the rightmost roots settle.

The constant-delay margin for a common delay ``tau`` (all ``tau_i = tau``) uses the
Kronecker-sum test of Chen, Gu & Nett (1995): ``j w`` is a root for ``z = exp(-j w tau)``
only if ``z`` solves the quadratic eigenvalue problem
``z^2 (S (x) I) + z (A (+) A) + (I (x) S) = 0`` on the unit circle, where
``A = E^-1 A0`` and ``S = E^-1 sum_i A_i``. The smallest such crossing delay is then
checked with the collocation spectrum.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from certify.system import LinearDelaySystem

__all__ = ["exact_constant_margin", "rightmost_roots", "spectral_abscissa", "stability_intervals"]

Complex = NDArray[np.complex128]

_START_NODES = 16
_MAX_NODES = 512
_NEWTON_ITER = 50
_UNIT_TOL = 1e-6
_AXIS_TOL = 1e-6
_VERIFY_FRACTIONS = (0.125, 0.25, 0.5, 0.75, 0.9, 0.99)


def _check_system(system: LinearDelaySystem) -> LinearDelaySystem:
    if not isinstance(system, LinearDelaySystem):
        raise ValueError(
            f"spectral methods need a single LinearDelaySystem, got {type(system).__name__}"
        )
    return system


def _check_delays(
    system: LinearDelaySystem, delays: float | Sequence[float]
) -> NDArray[np.float64]:
    tau = np.array(delays, dtype=np.float64).reshape(-1)
    if tau.size == 1:
        tau = np.full(system.m, tau[0])
    if tau.size != system.m:
        raise ValueError(f"expected {system.m} delays (one per A_i), got {tau.size}")
    if not np.all(np.isfinite(tau)) or np.any(tau < 0):
        raise ValueError(f"delays must be finite and nonnegative, got {tau.tolist()}")
    return tau


def _scale(system: LinearDelaySystem) -> float:
    a0, mats = system.explicit()
    return max(1.0, float(np.linalg.norm(a0, 2)), *(float(np.linalg.norm(a, 2)) for a in mats))


def _chebyshev(nodes: int, length: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev points ``0 = theta_0 > ... > theta_N = -length`` and differentiation matrix."""
    j = np.arange(nodes + 1)
    x = np.cos(np.pi * j / nodes)
    c = np.where((j == 0) | (j == nodes), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    d = np.outer(c, 1.0 / c) / (dx + np.eye(nodes + 1))
    d -= np.diag(d.sum(axis=1))
    return 0.5 * length * (x - 1.0), d * (2.0 / length)


def _lagrange_row(theta: NDArray[np.float64], point: float) -> NDArray[np.float64]:
    """Values at ``point`` of the Lagrange basis on the Chebyshev points ``theta``."""
    hit = np.isclose(theta, point, rtol=0.0, atol=1e-14 * max(1.0, abs(point)))
    if hit.any():
        return hit.astype(np.float64) / hit.sum()
    nodes = theta.size - 1
    w = (-1.0) ** np.arange(nodes + 1)
    w[[0, -1]] *= 0.5
    terms = w / (point - theta)
    return terms / terms.sum()


def _generator_eigenvalues(
    system: LinearDelaySystem, tau: NDArray[np.float64], nodes: int
) -> Complex:
    """Eigenvalues of the collocated infinitesimal generator with ``nodes + 1`` points."""
    a0, mats = system.explicit()
    n = system.n
    theta, d = _chebyshev(nodes, float(tau.max()))
    big = np.kron(d, np.eye(n))
    big[:n, :] = 0.0
    big[:n, :n] = a0
    for a, t in zip(mats, tau, strict=True):
        big[:n, :] += np.kron(_lagrange_row(theta, -t)[None, :], a)
    return np.linalg.eigvals(big).astype(np.complex128)


def _characteristic(
    system: LinearDelaySystem, tau: NDArray[np.float64], lam: complex
) -> tuple[NDArray[Any], NDArray[Any]]:
    """``T(lambda) = lambda E - A0 - sum A_i e^{-lambda tau_i}`` and ``dT/dlambda``."""
    t_mat = lam * system.E_matrix - system.A0 + 0j
    dt_mat = system.E_matrix + 0j
    for a, ti in zip(system.A, tau, strict=True):
        ex = np.exp(-lam * ti)
        t_mat = t_mat - a * ex
        dt_mat = dt_mat + ti * ex * a
    return t_mat, dt_mat


def _newton(
    system: LinearDelaySystem, tau: NDArray[np.float64], lam: complex, tol: float
) -> complex | None:
    """Newton's method on ``det T(lambda)``: ``lambda -= 1 / trace(T^-1 T')``; None if it fails."""
    for _ in range(_NEWTON_ITER):
        t_mat, dt_mat = _characteristic(system, tau, lam)
        try:
            with np.errstate(divide="ignore", invalid="ignore"):
                step = 1.0 / np.trace(np.linalg.solve(t_mat, dt_mat))
        except np.linalg.LinAlgError:
            return lam  # T(lambda) exactly singular: lambda is a root
        if not np.isfinite(step):
            return lam
        lam = lam - step
        if abs(step) <= tol * (1.0 + abs(lam)):
            return complex(lam)
    return None


def _unique(roots: list[complex], tol: float) -> Complex:
    out: list[complex] = []
    for r in sorted(roots, key=lambda z: (-z.real, z.imag)):
        if all(abs(r - q) > tol * (1.0 + abs(r)) for q in out):
            out.append(r)
    return np.array(out, dtype=np.complex128)


def _contains(pool: Complex, roots: Complex, tol: float) -> bool:
    """Whether every root (or its conjugate: the spectrum is symmetric) is found in ``pool``."""
    if pool.size == 0:
        return roots.size == 0
    both = np.concatenate([pool, pool.conj()])
    return all(np.min(np.abs(both - r)) <= tol * (1.0 + abs(r)) for r in roots)


def _refined_rightmost(
    system: LinearDelaySystem, tau: NDArray[np.float64], nodes: int, k: int, tol: float
) -> Complex:
    eig = _generator_eigenvalues(system, tau, nodes)
    candidates = eig[np.argsort(-eig.real)][: 2 * k + 4]
    refined = [_newton(system, tau, complex(z), tol) for z in candidates]
    return _unique([r for r in refined if r is not None], 1e3 * tol)[:k]


def rightmost_roots(
    system: LinearDelaySystem,
    delays: float | Sequence[float],
    k: int = 6,
    *,
    exclude_zero: bool = False,
    tol: float = 1e-12,
) -> Complex:
    """Rightmost characteristic roots for constant delays.

    Parameters
    ----------
    system : LinearDelaySystem
        The system (``E`` must be invertible, which the constructor enforces).
    delays : float or sequence of float
        Constant delay per channel (a scalar applies to every channel).
    k : int, optional
        Number of roots to return.
    exclude_zero : bool, optional
        Drop roots at the origin (a structural zero root, e.g. of a teleoperator without
        operator spring).
    tol : float, optional
        Relative Newton tolerance. The node count doubles until the ``k`` rightmost refined
        roots of each level are found (at ``1e3 * tol``) among the ``k + 2`` of the other.

    Returns
    -------
    numpy.ndarray of complex
        Up to ``k`` distinct roots sorted by decreasing real part.

    Raises
    ------
    ValueError
        On a bad system, delays or ``k``.
    """
    system = _check_system(system)
    tau = _check_delays(system, delays)
    if k < 1:
        raise ValueError(f"k must be positive, got {k}")
    extra = 1 if exclude_zero else 0
    want = k + extra
    if tau.max() == 0.0:
        a0, mats = system.explicit()
        roots = _unique(list(np.linalg.eigvals(a0 + sum(mats)).astype(complex)), 1e3 * tol)
    else:
        nodes = _START_NODES
        roots = _refined_rightmost(system, tau, nodes, want + 2, tol)
        while nodes < _MAX_NODES:
            nodes *= 2
            finer = _refined_rightmost(system, tau, nodes, want + 2, tol)
            settled = _contains(finer, roots[:want], 1e3 * tol)
            settled = settled and _contains(roots, finer[:want], 1e3 * tol)
            roots = finer
            if settled:
                break
    if exclude_zero:
        roots = roots[np.abs(roots) > 1e-8 * _scale(system)]
    return roots[:k]


def spectral_abscissa(
    system: LinearDelaySystem, delays: float | Sequence[float], *, exclude_zero: bool = False
) -> float:
    """Largest real part of the characteristic roots for constant delays.

    Parameters
    ----------
    system : LinearDelaySystem
        The system.
    delays : float or sequence of float
        Constant delay per channel (a scalar applies to every channel).
    exclude_zero : bool, optional
        Ignore roots at the origin.

    Returns
    -------
    float
        The spectral abscissa (negative means exponentially stable).
    """
    roots = rightmost_roots(system, delays, k=4, exclude_zero=exclude_zero)
    return float(np.max(roots.real)) if roots.size else -math.inf


def _crossing_frequencies(system: LinearDelaySystem) -> list[tuple[float, float]]:
    """Pairs ``(theta, w)``: a root ``j w`` (``w > 0``) at each delay ``(theta + 2 pi k) / w``.

    The classical test for commensurate delays (Chen, Gu & Nett 1995): ``j w`` is a root for the
    delay ``tau`` iff ``z = exp(-j w tau)`` on the unit circle makes ``A_0 + z S`` (``S`` the sum
    of the delay matrices) have the eigenvalue ``j w``, and those ``z`` are the unit-modulus
    eigenvalues of a quadratic pencil in Kronecker form.
    """
    a0, mats = system.explicit()
    s = sum(mats)
    n = system.n
    eye = np.eye(n)
    m2, m1, m0 = np.kron(s, eye), np.kron(a0, eye) + np.kron(eye, a0), np.kron(eye, s)
    big = n * n
    lhs = np.block([[np.zeros((big, big)), np.eye(big)], [-m0, -m1]])
    rhs = np.block([[np.eye(big), np.zeros((big, big))], [np.zeros((big, big)), m2]])
    alpha, beta = scipy.linalg.eig(lhs, rhs, right=False, homogeneous_eigvals=True)
    finite = np.abs(beta) > 1e-12 * np.abs(alpha)
    z = alpha[finite] / beta[finite]
    pairs: list[tuple[float, float]] = []
    scale = _scale(system)
    for zk in z[np.abs(np.abs(z) - 1.0) < _UNIT_TOL]:
        zk = zk / abs(zk)
        for lam in np.linalg.eigvals(a0 + zk * s):
            if abs(lam.real) < _AXIS_TOL * scale and lam.imag > _AXIS_TOL * scale:
                pairs.append((float(np.mod(-np.angle(zk), 2.0 * np.pi)), float(lam.imag)))
    return pairs


def _crossing_delays(system: LinearDelaySystem, lower: float = 0.0,
                     upper: float = math.inf) -> list[float]:
    """Common delays in ``[lower, upper]`` with a root on the imaginary axis, sorted.

    With ``upper = inf`` only the first crossing at or above ``lower`` of each frequency.
    """
    taus: list[float] = []
    for theta, w in _crossing_frequencies(system):
        first = max(0, math.ceil((lower * w - theta) / (2.0 * math.pi) - 1e-12))
        k = first
        while True:
            tau = (theta + 2.0 * math.pi * k) / w
            if tau > upper or (math.isinf(upper) and k > first):
                break
            taus.append(tau)
            k += 1
    return sorted(t for t in taus if t >= lower)


def _first_unstable(system: LinearDelaySystem, taus: Sequence[float], zero: bool) -> float | None:
    for t in taus:
        if spectral_abscissa(system, t, exclude_zero=zero) >= 0.0:
            return t
    return None


def _bisect_onset(system: LinearDelaySystem, lo: float, hi: float, zero: bool) -> float:
    """Shrink ``[lo, hi]`` (stable at ``lo``, not at ``hi``) to the onset of instability."""
    while hi - lo > 1e-9 * hi:
        mid = 0.5 * (lo + hi)
        if spectral_abscissa(system, mid, exclude_zero=zero) >= 0.0:
            hi = mid
        else:
            lo = mid
    return lo


def _check_lower(lower: float) -> float:
    value = float(lower)
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"lower must be a finite delay >= 0, got {lower!r}")
    return value


def exact_constant_margin(system: LinearDelaySystem, lower: float = 0.0, *,
                          exclude_zero: bool = False) -> float:
    """Largest ``h`` with stability for every common constant delay in ``[lower, h]``.

    Parameters
    ----------
    system : LinearDelaySystem
        The system.
    lower : float, optional
        Smallest delay (a minimum latency): a system may be stable only on an interval of
        delays that does not contain 0 (:func:`stability_intervals`).
    exclude_zero : bool, optional
        Ignore a structural root at the origin (present for every delay).

    Returns
    -------
    float
        ``0.0`` if unstable at ``lower``, ``math.inf`` if stable for every common constant delay
        above it, otherwise the smallest delay above ``lower`` with a root on the imaginary axis.
    """
    system = _check_system(system)
    lower = _check_lower(lower)
    if spectral_abscissa(system, lower, exclude_zero=exclude_zero) >= 0.0:
        return 0.0
    crossings = [t for t in _crossing_delays(system, lower) if t > lower]
    if crossings:
        margin = crossings[0]
        grid = [lower + f * (margin - lower) for f in _VERIFY_FRACTIONS]
    else:
        margin = math.inf
        grid = [lower + 2.0**p / _scale(system) for p in range(-2, 4)]
    unstable = _first_unstable(system, grid, exclude_zero)
    if unstable is None:
        return margin
    previous = max([t for t in grid if t < unstable], default=lower)
    return _bisect_onset(system, previous, unstable, exclude_zero)


def stability_intervals(system: LinearDelaySystem, h_max: float, *,
                        exclude_zero: bool = False) -> list[tuple[float, float]]:
    """The common constant delays in ``[0, h_max]`` for which the system is stable.

    Between two consecutive delays with a root on the imaginary axis the number of roots in
    the right half-plane is constant, so each such segment is stable or unstable as a whole;
    the midpoint of each is checked with the collocation spectrum.

    Parameters
    ----------
    system : LinearDelaySystem
        The system.
    h_max : float
        Largest delay considered.
    exclude_zero : bool, optional
        Ignore a structural root at the origin.

    Returns
    -------
    list of (float, float)
        Disjoint intervals ``(a, b)``, increasing; the system is exponentially stable for every
        common constant delay strictly inside each (and at ``a = 0`` when it is stable without
        delay). ``b = h_max`` when the last interval reaches it.
    """
    system = _check_system(system)
    if not (math.isfinite(h_max) and h_max > 0):
        raise ValueError(f"h_max must be finite and positive, got {h_max!r}")
    cuts = sorted({0.0, *(t for t in _crossing_delays(system, 0.0, h_max) if t < h_max), h_max})
    stable = [spectral_abscissa(system, 0.5 * (a + b), exclude_zero=exclude_zero) < 0.0
              for a, b in itertools.pairwise(cuts)]
    intervals: list[tuple[float, float]] = []
    for (a, b), good in zip(itertools.pairwise(cuts), stable, strict=True):
        if good and intervals and intervals[-1][1] == a:
            intervals[-1] = (intervals[-1][0], b)  # a tangential touch of the axis
        elif good:
            intervals.append((a, b))
    return intervals
