from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from certify import (
    Certificate,
    LinearDelaySystem,
    PolytopicDelaySystem,
    bisection,
    certify_delay,
    max_delay,
    max_delay_certificate,
)
from certify.bisection import SCAN_TRIES

BENCHMARK_EXACT = 6.172581371  # arccos(-0.9) / sqrt(0.19)

# (method, mu, published bound) for A = [[-2,0],[0,-0.9]], Ad = [[-1,0],[-1,-1]]
BENCHMARK_PUBLISHED = [
    ("jensen", None, 1.345),  # Jensen on both sub-intervals, fast-varying delay
    ("rcc", None, 1.867),  # Park, Ko & Jeong (2011), fast-varying delay
    ("jensen", 0.0, 4.472),  # constant delay
    ("wirtinger", 0.0, 6.059),  # Seuret & Gouaisbaut (2013), constant delay
]


@pytest.mark.parametrize(("method", "mu", "published"), BENCHMARK_PUBLISHED)
def test_benchmark_matches_published_bounds(benchmark_system, method, mu, published):
    h = max_delay(benchmark_system, method=method, mu=mu)
    assert h == pytest.approx(published, rel=0.02)
    assert h < BENCHMARK_EXACT


@pytest.mark.parametrize("mu", [None, 0.5, 0.0])
def test_benchmark_methods_ordered_and_below_exact(benchmark_system, mu):
    h = {m: max_delay(benchmark_system, method=m, mu=mu) for m in ("jensen", "rcc", "wirtinger")}
    assert h["jensen"] <= h["rcc"] * 1.002
    assert h["rcc"] <= h["wirtinger"] * 1.002
    assert max(h.values()) < BENCHMARK_EXACT
    assert max_delay(benchmark_system, mu=mu) >= 0.998 * h["wirtinger"]


@pytest.mark.parametrize("method", ["jensen", "rcc", "wirtinger", "io"])
def test_scalar_time_varying_never_beats_three_halves(scalar_system, method):
    # x' = -x(t - tau(t)) is stable for all tau(t) <= h iff h < 3/2 (Myshkis, Yorke)
    assert max_delay(scalar_system, method=method) < 1.5


def test_scalar_published_values(scalar_system):
    assert max_delay(scalar_system, method="rcc") == pytest.approx(1.34, rel=0.02)
    assert max_delay(scalar_system, method="io") == pytest.approx(1.0, rel=0.02)
    assert max_delay(scalar_system, method="wirtinger", mu=0.0) < math.pi / 2


def test_fast_varying_bound_below_constant_bound(benchmark_system):
    assert max_delay(benchmark_system, "wirtinger") <= max_delay(benchmark_system, "wirtinger", 0.0)


@pytest.mark.parametrize("method", ["rcc", "io"])
def test_descriptor_form_matches_explicit_form(benchmark_system, method):
    e = np.array([[2.0, 1.0], [0.0, 0.5]])
    desc = LinearDelaySystem(e @ benchmark_system.A0, [e @ benchmark_system.A[0]], E=e)
    assert max_delay(desc, method) == pytest.approx(max_delay(benchmark_system, method), rel=5e-3)


def test_two_independent_delays_and_weights(benchmark_system):
    half = 0.5 * benchmark_system.A[0]
    split = LinearDelaySystem(benchmark_system.A0, [half, half])
    common = max_delay(split, "rcc")
    assert 0 < common < BENCHMARK_EXACT
    cert = max_delay_certificate(split, "rcc", weights=[1.0, 0.5])
    assert cert.certified and cert.delay_bounds[1] == pytest.approx(0.5 * cert.delay_bounds[0])
    assert cert.margin is not None and cert.margin >= common * 0.999


def _polytope(benchmark_system: LinearDelaySystem) -> PolytopicDelaySystem:
    a0 = benchmark_system.A0
    ad = benchmark_system.A[0]
    e2 = np.array([[1.0, 0.2], [0.0, 1.5]])
    return PolytopicDelaySystem.polytope(
        [
            benchmark_system,
            LinearDelaySystem(a0 + np.array([[0.0, 0.3], [0.0, 0.0]]), [1.2 * ad]),
            LinearDelaySystem(e2 @ a0, [e2 @ ad], E=e2),
        ]
    )


@pytest.mark.parametrize(("method", "mu"), [("rcc", None), ("wirtinger", 0.0), ("io", None)])
def test_common_functional_certifies_interior_points(benchmark_system, method, mu):
    poly = _polytope(benchmark_system)
    cert = max_delay_certificate(poly, method, mu)
    assert cert.certified and cert.verify()
    h_poly = cert.delay_bounds
    rng = np.random.default_rng(7)
    for _ in range(3):
        point = poly.point(rng.dirichlet(np.ones(3)))
        assert certify_delay(point, h_poly, method, mu).certified
        # the polytope's own matrices certify the point (LMIs affine in the system)
        moved = dataclasses.replace(cert, system=PolytopicDelaySystem((point,)))
        assert moved.verify()
    # every vertex alone does at least as well as the polytope
    for vertex in poly.vertices:
        assert max_delay(vertex, method, mu) >= 0.999 * h_poly[0]


def test_certify_delay_verdicts(benchmark_system):
    assert certify_delay(benchmark_system, 1.0, "rcc").certified
    cert = certify_delay(benchmark_system, 1.9, "rcc")
    assert not cert.certified and cert.matrices == {}
    auto = certify_delay(benchmark_system, 2.0)  # rcc fails here, wirtinger does not
    assert auto.certified and auto.method == "wirtinger"


def test_nothing_certifiable_returns_zero():
    unstable = LinearDelaySystem(np.array([[0.5]]), [np.array([[-0.1]])])
    cert = max_delay_certificate(unstable, "rcc")
    assert cert.margin == 0.0 and not cert.certified


def _counting_solves(monkeypatch) -> list[int]:
    """Count the LMI solves of the searches that follow."""
    from certify.solve import LMIProblem

    count = [0]
    solve = LMIProblem.solve

    def counted(self, h):
        count[0] += 1
        return solve(self, h)

    monkeypatch.setattr(LMIProblem, "solve", counted)
    return count


def test_h_min_ends_a_search_that_finds_nothing_early(monkeypatch):
    unstable = LinearDelaySystem(np.array([[0.5]]), [np.array([[-0.1]])])
    count = _counting_solves(monkeypatch)
    assert max_delay_certificate(unstable, "rcc", channels="reduced").margin == 0.0
    to_the_end, count[0] = count[0], 0
    cert = max_delay_certificate(unstable, "rcc", channels="reduced", h_max=1.0, h_min=0.01)
    assert cert.margin == 0.0 and not cert.certified
    assert count[0] <= SCAN_TRIES + 1 < to_the_end  # the scan up, then h_min, then done


def test_h_min_at_the_systems_time_scale_is_tried_first(monkeypatch):
    unstable = LinearDelaySystem(np.array([[0.5]]), [np.array([[-0.1]])])  # guess 1 / 0.6 s
    count = _counting_solves(monkeypatch)
    cert = max_delay_certificate(unstable, "rcc", channels="reduced", h_max=10.0, h_min=2.0)
    assert cert.margin == 0.0 and not cert.certified and count[0] == 1
    assert cert.delay_bounds == (2.0,)


@pytest.mark.parametrize("h_min", [0.1, 0.5])  # below and above the guess (0.43 s)
def test_h_min_leaves_a_found_margin_alone(benchmark_system, h_min):
    assert max_delay(benchmark_system, "rcc", h_min=h_min) == pytest.approx(
        max_delay(benchmark_system, "rcc"), rel=1e-3)


def test_h_min_tried_after_a_failed_guess_still_finds_the_margin(benchmark_system, monkeypatch):
    expected = max_delay(benchmark_system, "rcc", rtol=1e-3)
    monkeypatch.setattr(bisection, "_initial_guess", lambda system: 50.0)  # far above 1.87
    found = max_delay(benchmark_system, "rcc", rtol=1e-3, h_min=0.1)
    assert found == pytest.approx(expected, rel=2e-3)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"h_min": -0.1}, "h_min"),
        ({"h_min": 2e3}, "h_min"),
        ({"method": "nope"}, "unknown method"),
        ({"mu": 1.0}, "mu"),
        ({"mu": -0.1}, "mu"),
        ({"weights": [1.0, 2.0]}, "weights"),
        ({"weights": -1.0}, "positive"),
        ({"h_max": math.inf}, "h_max"),
    ],
)
def test_max_delay_bad_input(benchmark_system, kwargs, message):
    with pytest.raises(ValueError, match=message):
        max_delay(benchmark_system, **kwargs)


def test_certify_delay_bad_input(benchmark_system):
    with pytest.raises(ValueError, match="h"):
        certify_delay(benchmark_system, [0.0])
    with pytest.raises(ValueError, match="LinearDelaySystem"):
        certify_delay("not a system", 1.0)  # type: ignore[arg-type]


@pytest.mark.parametrize(("method", "mu"), [("rcc", None), ("io", None)])
def test_frozen_parameter_uses_vertex_functionals(benchmark_system, method, mu):
    switching = _polytope(benchmark_system)
    frozen = PolytopicDelaySystem.polytope(switching.vertices, variation="frozen")
    cert = max_delay_certificate(frozen, method, mu)
    assert cert.certified and cert.verify()
    assert cert.margin >= 0.999 * max_delay(switching, method, mu)
    assert any("fixed (time-invariant)" in a for a in cert.assumptions)
    back = Certificate.from_json(cert.to_json())
    assert back.system.frozen and back.verify()
    # interpolating the vertex functionals certifies each fixed interior point
    weights = np.random.default_rng(3).dirichlet(np.ones(3))
    point = frozen.point(weights)
    names = {k.split("@")[0] for k in cert.matrices if "@" in k}
    mats = {k: v for k, v in cert.matrices.items() if k.startswith("N")}
    mats |= {x: sum(w * cert.matrices[f"{x}@{k}"] for k, w in enumerate(weights)) for x in names}
    moved = dataclasses.replace(cert, system=PolytopicDelaySystem((point,)), matrices=mats)
    assert moved.verify()
    assert certify_delay(point, cert.delay_bounds, method, mu).certified


def test_a_thread_cap_leaves_the_verdict_alone(benchmark_system):
    free = certify_delay(benchmark_system, 4.0, method="jensen", mu=0.0)
    capped = certify_delay(benchmark_system, 4.0, method="jensen", mu=0.0, threads=1)
    assert capped.certified and free.certified
    with pytest.raises(ValueError, match="threads must be 0"):
        certify_delay(benchmark_system, 4.0, method="jensen", mu=0.0, threads=-1)
