"""Interval delays ``l <= tau(t) <= h`` and the channel forms of the LMIs."""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np
import pytest

from certify import (
    Certificate,
    LinearDelaySystem,
    certify_delay,
    exact_constant_margin,
    max_delay,
    max_delay_certificate,
)

# Gu, Kharitonov & Chen (2003), p. 193: stable only for constant delays in (0.100174, 1.71785).
DELAY_STABILISED = LinearDelaySystem(np.array([[0.0, 1.0], [-2.0, 0.1]]),
                                     [np.array([[0.0, 0.0], [1.0, 0.0]])])
# A rank-one delay matrix: the reduced functional acts on one signal instead of two states.
RANK_ONE = LinearDelaySystem(np.array([[0.0, 1.0], [-1.0, -2.0]]),
                             [np.array([[0.0, 0.0], [-1.0, 1.0]])])


def _textbook_interval_rcc(a: np.ndarray, ad: np.ndarray, h1: float, h2: float) -> bool:
    """Jensen + reciprocally convex LMI for fast-varying delays in ``[h1, h2]``, written directly.

    ``V = x'Px + int_{t-h1}^t x'Q1x + int_{t-h2}^t x'Q2x + h1 int int x''R1x'
    + (h2-h1) int int x''R2x'`` on ``xi = [x, x(t-h1), x(t-tau), x(t-h2)]`` with ``x'`` substituted
    (no descriptor slack): an independent reference for the library's interval RCC.
    """
    n = len(a)
    e = [np.hstack([np.eye(n) if j == k else np.zeros((n, n)) for j in range(4)])
         for k in range(4)]
    ac = a @ e[0] + ad @ e[2]
    p, q1, q2, r1, r2 = (cp.Variable((n, n), symmetric=True) for _ in range(5))
    s = cp.Variable((n, n))
    span = h2 - h1
    phi = (e[0].T @ p @ ac + ac.T @ p @ e[0] + e[0].T @ (q1 + q2) @ e[0] - e[1].T @ q1 @ e[1]
           - e[3].T @ q2 @ e[3] + ac.T @ (h1**2 * r1 + span**2 * r2) @ ac
           - (e[0] - e[1]).T @ r1 @ (e[0] - e[1]))
    pair = np.vstack([e[1] - e[2], e[2] - e[3]])
    rcc = cp.bmat([[r2, s], [s.T, r2]])
    phi = phi - pair.T @ rcc @ pair
    t = cp.Variable()
    positive = [p, q1, q2, r1, rcc]
    constraints = [m >> t * np.eye(m.shape[0]) for m in positive]
    constraints += [-0.5 * (phi + phi.T) >> t * np.eye(4 * n), t <= 1e-4,
                    sum(cp.trace(m) for m in positive) <= 1]
    problem = cp.Problem(cp.Maximize(t), constraints)
    try:
        with warnings.catch_warnings():  # an inaccurate solve is rejected below
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver="CLARABEL")
    except cp.SolverError:
        return False
    if problem.status != cp.OPTIMAL or t.value is None or t.value <= 0:
        return False
    # re-check in numpy, relative to each matrix's scale
    checks = [m.value for m in positive] + [-0.5 * (phi.value + phi.value.T)]
    return all(np.linalg.eigvalsh(0.5 * (m + m.T))[0] > 1e-9 * np.abs(m).max() for m in checks)


def _textbook_margin(a: np.ndarray, ad: np.ndarray, h1: float) -> float:
    lo, hi = h1, 10.0
    while hi - lo > 1e-3 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _textbook_interval_rcc(a, ad, h1, mid) else (lo, mid)
    return lo


@pytest.mark.parametrize("h1", [0.5, 1.0, 2.0])
def test_interval_rcc_matches_a_textbook_lmi(benchmark_system, h1):
    a, (ad,) = benchmark_system.A0, benchmark_system.A
    reference = _textbook_margin(a, ad, h1)
    margin = max_delay(benchmark_system, "rcc", None, h1)  # max_delay(system, method, mu, lower)
    assert margin == pytest.approx(reference, rel=3e-3)
    assert h1 < margin < exact_constant_margin(benchmark_system, h1)


def test_a_tiny_lower_bound_changes_almost_nothing(benchmark_system):
    for method in ("rcc", "wirtinger"):
        assert max_delay(benchmark_system, method, lower=1e-6) == pytest.approx(
            max_delay(benchmark_system, method), rel=3e-3)


def test_wirtinger_interval_at_least_rcc(benchmark_system):
    for h1 in (0.5, 2.0):
        assert (max_delay(benchmark_system, "wirtinger", lower=h1)
                >= 0.999 * max_delay(benchmark_system, "rcc", lower=h1))


@pytest.mark.parametrize("mu", [None, 0.0])
def test_delay_stabilised_system_certified_inside_its_exact_interval(mu):
    assert max_delay(DELAY_STABILISED, "wirtinger", mu, lower=0.05, rtol=0.02) == 0.0
    for lower in (0.2, 1.0):
        margin = max_delay(DELAY_STABILISED, "wirtinger", mu, lower=lower, rtol=0.01)
        assert lower < margin < exact_constant_margin(DELAY_STABILISED, lower)
    assert exact_constant_margin(DELAY_STABILISED, 0.5) == pytest.approx(1.71785, abs=1e-5)


def test_interval_certificate_round_trip_and_tampering():
    cert = certify_delay(DELAY_STABILISED, 1.2, "wirtinger", lower=0.5)
    assert cert.certified and cert.verify()
    assert cert.delay_lower == (0.5,)
    assert any("l = 0.5" in text for text in cert.assumptions)
    back = Certificate.from_json(cert.to_json())
    assert back.delay_lower == (0.5,) and back.verify()
    data = cert.to_dict()
    for lower in ([], [0.0], [1.3], [-0.1]):
        assert not Certificate.from_dict({**data, "delay_lower": lower}).verify()
    assert not certify_delay(DELAY_STABILISED, 1.2, "wirtinger").certified


def test_io_ignores_a_lower_bound_and_says_so(benchmark_system):
    cert = max_delay_certificate(benchmark_system, "io", lower=0.5)
    assert cert.margin == pytest.approx(max_delay(benchmark_system, "io"), rel=3e-3)
    assert any("lower delay bounds are not used" in text for text in cert.assumptions)


def test_lower_bound_input_errors(benchmark_system):
    with pytest.raises(ValueError, match="exceed the upper bounds"):
        certify_delay(benchmark_system, 0.5, "rcc", lower=1.0)
    with pytest.raises(ValueError, match="finite and >= 0"):
        max_delay(benchmark_system, "rcc", lower=-1.0)
    with pytest.raises(ValueError, match="reach h_max"):
        max_delay(benchmark_system, "rcc", lower=5.0, h_max=4.0)
    with pytest.raises(ValueError, match="channels must be"):
        max_delay(benchmark_system, "rcc", channels="half")


@pytest.mark.parametrize("method", ["rcc", "wirtinger"])
@pytest.mark.parametrize("mu", [0.1, 0.5])
def test_default_at_least_as_tight_as_the_full_state_form(method, mu):
    full = max_delay(RANK_ONE, method, mu, channels="full")
    reduced = max_delay(RANK_ONE, method, mu, channels="reduced")
    assert max_delay(RANK_ONE, method, mu) >= full * (1 - 1e-9)
    assert reduced < full  # the loss the default avoids is real here


def test_channel_form_recorded_in_the_certificate():
    full = certify_delay(RANK_ONE, 1.0, "rcc", 0.5, channels="full")
    reduced = certify_delay(RANK_ONE, 1.0, "rcc", 0.5, channels="reduced")
    assert [c.shape for c in full.channels] == [(2, 2)]
    assert [c.shape for c in reduced.channels] == [(1, 2)]
    assert full.verify() and reduced.verify()
    assert any("whole state" in text for text in full.assumptions)
