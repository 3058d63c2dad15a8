"""Public LMI entry points: certify given delay bounds, or find the largest certified bound."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from certify.certificate import Certificate
from certify.channels import MODES, Channels
from certify.conditions import check_mu, lower_bounds
from certify.methods import AUTO_METHODS, get_method
from certify.solve import LMIProblem
from certify.system import LinearDelaySystem, PolytopicDelaySystem, as_polytope

__all__ = ["certify_delay", "max_delay", "max_delay_certificate"]

System = LinearDelaySystem | PolytopicDelaySystem


def _method_names(method: str) -> tuple[str, ...]:
    if method == "auto":
        return AUTO_METHODS
    get_method(method)
    return (method,)


def _problems(system: PolytopicDelaySystem, method: str, mu: float | None,
              lower: tuple[float, ...], channels: str, retry: str = "always", threads: int = 0
              ) -> list[LMIProblem]:
    """The problems to try: each method, in each channel form (``"auto"``: both if they differ).

    The reduced form comes first: it is smaller, and where it certifies, the full form is only
    tried by a bisection that may find a larger bound.
    """
    if channels == "auto":
        modes = MODES if Channels.of(system).reduced else MODES[:1]
    elif channels in MODES:
        modes = (channels,)
    else:
        raise ValueError(f"channels must be auto, {', '.join(MODES)}; got {channels!r}")
    return [LMIProblem(system, get_method(name), mu, lower, mode, retry, threads)
            for name in _method_names(method) for mode in modes]


def _positive_vector(values: float | Sequence[float], m: int, what: str) -> np.ndarray:
    vec = np.array(values, dtype=np.float64).reshape(-1)
    if vec.size == 1:
        vec = np.full(m, vec[0])
    if vec.size != m:
        raise ValueError(f"{what} needs {m} entries (one per delay), got {vec.size}")
    if not np.all(np.isfinite(vec)) or np.any(vec <= 0):
        raise ValueError(f"{what} must be finite and positive, got {vec.tolist()}")
    return vec


def certify_delay(
    system: System,
    h: float | Sequence[float],
    method: str = "auto",
    mu: float | None = None,
    *,
    lower: float | Sequence[float] = 0.0,
    channels: str = "auto",
    retry: str = "always",
    threads: int = 0,
) -> Certificate:
    """Certify stability for given delay bounds, ``lower_i <= tau_i(t) <= h_i``.

    Parameters
    ----------
    system : LinearDelaySystem or PolytopicDelaySystem
        The system; a polytope is certified as a whole, for a parameter that switches
        arbitrarily fast or is frozen, as its ``variation`` says.
    h : float or sequence of float
        Upper bound of each delay (a scalar applies to every delay).
    method : str, optional
        ``"jensen"``, ``"rcc"``, ``"wirtinger"``, ``"io"`` or ``"auto"`` (tries
        ``wirtinger`` then ``io`` and returns the first certificate found).
    mu : float or None, optional
        ``None``: time-varying delays with unknown derivative; ``0.0``: constant delays;
        ``0 < mu < 1``: ``tau_i'(t) <= mu``.
    lower : float or sequence of float, optional
        Lower bound of each delay (a minimum latency; default 0). Each must not exceed ``h``.
    channels : str, optional
        ``"auto"`` (default): the functional on the delayed signals ``y_i = C_i x``, then, if
        that fails and some ``A_i`` is rank-deficient, on the whole state
        (:mod:`certify.channels`); ``"reduced"`` or ``"full"`` for one form only.
    retry : {"always", "accurate"}, optional
        When a failed solve is tried again in balanced coordinates
        (:class:`~certify.solve.LMIProblem`).
    threads : int, optional
        Most threads of the solver's linear algebra (0, the default: the solver's choice).

    Returns
    -------
    Certificate
        The certificate (``certified`` tells the verdict).

    Raises
    ------
    ValueError
        On an unknown method, bad bounds or bad ``mu``.
    """
    poly = as_polytope(system)
    bounds = _positive_vector(h, poly.m, "h")
    low = _checked_lower(lower, bounds)
    mu = check_mu(mu)
    cert: Certificate | None = None
    for problem in _problems(poly, method, mu, low, channels, retry, threads):
        cert = problem.solve(bounds)
        if cert.certified:
            break
    assert cert is not None
    return cert


def _checked_lower(lower: float | Sequence[float], upper: np.ndarray) -> tuple[float, ...]:
    """Lower bounds, each at most its upper bound."""
    low = lower_bounds(lower, len(upper))
    if any(a > b for a, b in zip(low, upper, strict=True)):
        raise ValueError(f"lower delay bounds {list(low)} exceed the upper bounds "
                         f"{upper.tolist()}")
    return low


def _initial_guess(system: PolytopicDelaySystem) -> float:
    """A delay of the order of the system's fastest time constant."""
    norms = [
        np.linalg.norm(np.hstack([a0, *mats]), 2)
        for a0, mats in (v.explicit() for v in system.corners())
    ]
    return 1.0 / max(1e-12, float(max(norms)))


SCAN_TRIES = 4
SCAN_FACTOR = 8.0
"""When the initial guess is not certified, the bisection first tries up to three bounds
``SCAN_FACTOR`` times larger each (at bounds far below the system's time scales the LMIs are
badly conditioned and the numpy re-check may reject a solution that exists), then, if none is
certified, bisects below the guess."""


def _bisect(
    problem: LMIProblem, weights: np.ndarray, guess: float, h_max: float, rtol: float,
    h_min: float = 0.0,
) -> Certificate:
    """Largest scale ``s <= h_max`` such that ``s * weights`` is certified (bisection).

    Scales start at the smallest one whose bounds reach the lower bounds (a certificate for
    ``[l, h]`` also covers every smaller upper bound, so the certified scales form an interval).
    Scales less than ``h_min`` above that smallest one are not searched: the scale ``h_min``
    above it is tried first when it is not below the guess (the system's time scale, under
    which bounds can fail numerically), else right after the guess fails; if it fails, the
    search ends (0).
    """
    best: Certificate | None = None
    floor = max(low / w for low, w in zip(problem.lower, weights, strict=True))
    if floor >= h_max:
        raise ValueError(f"the lower delay bounds {list(problem.lower)} reach h_max = {h_max}")
    guess = max(guess, 2.0 * floor)
    worth = floor + h_min if h_min > 0.0 else math.inf  # the smallest scale worth certifying
    if guess <= worth < h_max:  # not below the system's time scale: it fails for real
        guess = worth
    lo, hi = floor, min(guess, h_max)
    cert = problem.solve(hi * weights)
    if not cert.certified and hi == worth:
        return dataclasses.replace(cert, margin=0.0)
    for _ in range(SCAN_TRIES - 1):  # a tiny bound can fail numerically: look further up
        if cert.certified or hi >= h_max:
            break
        hi = min(SCAN_FACTOR * hi, h_max)
        cert = problem.solve(hi * weights)
    if not cert.certified:  # nothing above the guess: bisect below it
        hi = min(guess, h_max)
        cert = problem.solve(hi * weights) if floor else cert
    if not cert.certified and worth < hi:  # one solve instead of a bisection down to it
        smallest = problem.solve(worth * weights)
        if not smallest.certified:
            return dataclasses.replace(smallest, margin=0.0)
        lo, best = worth, smallest
    while cert.certified:  # expand until a failure or h_max
        lo, best = hi, cert
        if hi >= h_max:
            return dataclasses.replace(cert, margin=lo)
        hi = min(2.0 * hi, h_max)
        cert = problem.solve(hi * weights)
    first_failure = cert
    while hi - lo > rtol * hi and hi - floor > max(1e-9 * guess, h_min):
        mid = 0.5 * (lo + hi)
        cert = problem.solve(mid * weights)
        if cert.certified:
            lo, best = mid, cert
        else:
            hi = mid
    if best is None:
        return dataclasses.replace(first_failure, margin=0.0)
    return dataclasses.replace(best, margin=lo)


def max_delay_certificate(
    system: System,
    method: str = "auto",
    mu: float | None = None,
    lower: float | Sequence[float] = 0.0,
    *,
    weights: float | Sequence[float] = 1.0,
    h_max: float = 1e3,
    rtol: float = 1e-3,
    channels: str = "auto",
    h_min: float = 0.0,
    threads: int = 0,
) -> Certificate:
    """Largest certified delay bound by bisection, with its certificate.

    Parameters
    ----------
    system : LinearDelaySystem or PolytopicDelaySystem
        The system.
    method : str, optional
        ``"jensen"``, ``"rcc"``, ``"wirtinger"``, ``"io"`` or ``"auto"`` (runs ``wirtinger``
        and ``io`` and keeps the larger bound).
    mu : float or None, optional
        Delay class as in :func:`certify_delay`.
    lower : float or sequence of float, optional
        Lower bound of each delay (default 0): the certificate is for
        ``lower_i <= tau_i(t) <= s * weights[i]``.
    weights : float or sequence of float, optional
        Relative delay bounds: the certificate is for ``h_i = s * weights[i]`` and ``s`` is
        maximised (default: one common bound ``h``).
    h_max : float, optional
        Largest scale tried; returned if it is certified.
    rtol : float, optional
        Relative width at which the bisection stops.
    channels : str, optional
        ``"auto"`` (default: both channel forms where they differ, the larger bound kept),
        ``"reduced"`` or ``"full"`` (:mod:`certify.channels`).
    h_min : float, optional
        Smallest scale above the lower bounds worth certifying: if the initial guess fails,
        this scale is tried next and, if it fails too, 0 is returned at once (default 0: the
        search then narrows to 1e-9 of the system's time scale, some thirty solves when
        nothing is certified).
    threads : int, optional
        Most threads of the solver's linear algebra (0, the default: the solver's choice).

    Returns
    -------
    Certificate
        Certificate at the largest certified scale, which is stored in ``margin``
        (``0.0`` with ``certified=False`` if no bound above the lower ones was certified).
    """
    poly = as_polytope(system)
    w = _positive_vector(weights, poly.m, "weights")
    mu = check_mu(mu)
    if not (h_max > 0 and math.isfinite(h_max)) or not 0 < rtol < 1:
        raise ValueError(f"need 0 < h_max < inf and 0 < rtol < 1, got {h_max}, {rtol}")
    if not 0 <= h_min < h_max:
        raise ValueError(f"need 0 <= h_min < h_max, got h_min = {h_min}, h_max = {h_max}")
    low = lower_bounds(lower, poly.m)
    guess = _initial_guess(poly)
    results = [_bisect(problem, w, guess, h_max, rtol, h_min)
               for problem in _problems(poly, method, mu, low, channels, threads=threads)]
    return max(results, key=lambda c: c.margin or 0.0)


def max_delay(
    system: System,
    method: str = "auto",
    mu: float | None = None,
    lower: float | Sequence[float] = 0.0,
    *,
    weights: float | Sequence[float] = 1.0,
    h_max: float = 1e3,
    rtol: float = 1e-3,
    channels: str = "auto",
    h_min: float = 0.0,
    threads: int = 0,
) -> float:
    """Largest common delay bound ``h`` certified for every delay (``lower <= tau_i(t) <= h``).

    Parameters
    ----------
    system : LinearDelaySystem or PolytopicDelaySystem
        The system.
    method : str, optional
        ``"jensen"``, ``"rcc"``, ``"wirtinger"``, ``"io"`` or ``"auto"`` (default, the best
        of ``wirtinger`` and ``io``).
    mu : float or None, optional
        ``None``: time-varying delays with unknown derivative; ``0.0``: constant delays;
        ``0 < mu < 1``: ``tau_i'(t) <= mu``.
    lower : float or sequence of float, optional
        Lower bound of each delay (a minimum latency; default 0).
    weights : float or sequence of float, optional
        Relative delay bounds (``h_i = h * weights[i]``); default one common bound.
    h_max : float, optional
        Largest bound tried.
    rtol : float, optional
        Relative bisection tolerance; the result is certified and within about ``rtol``
        of the method's limit.
    channels : str, optional
        Channel forms tried (:func:`max_delay_certificate`).
    h_min : float, optional
        Smallest bound above ``lower`` worth searching (:func:`max_delay_certificate`).
    threads : int, optional
        Most threads of the solver's linear algebra (0, the default: the solver's choice).

    Returns
    -------
    float
        The certified bound (``0.0`` if none).
    """
    cert = max_delay_certificate(system, method, mu, weights=weights, h_max=h_max, rtol=rtol,
                                 lower=lower, channels=channels, h_min=h_min, threads=threads)
    return float(cert.margin or 0.0)
