from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from certify import (
    LinearDelaySystem,
    PolytopicDelaySystem,
    exact_constant_margin,
    max_delay,
    max_delay_certificate,
)
from certify.channels import Channels
from certify.methods import METHODS
from certify.solve import LMIProblem


@pytest.fixture(scope="module")
def rank_one() -> LinearDelaySystem:
    """Delay acting through one output only: x' = A x + b c^T x(t - tau)."""
    a0 = np.array([[0.0, 1.0, 0.0], [-2.0, -1.0, 0.5], [0.0, 0.3, -1.5]])
    b = np.array([[0.0], [-1.0], [0.4]])
    c = np.array([[1.0, 0.0, 0.2]])
    return LinearDelaySystem(a0, [b @ c])


def test_full_rank_channel_is_identity(benchmark_system):
    ch = Channels.of(PolytopicDelaySystem((benchmark_system,)))
    assert ch.r == (2,) and ch.coef(0) == 1.0


def test_rank_deficient_channel_is_reduced(rank_one):
    poly = PolytopicDelaySystem((rank_one, LinearDelaySystem(rank_one.A0, [2 * rank_one.A[0]])))
    ch = Channels.of(poly)
    assert ch.r == (1,) and ch.valid_for(poly)
    np.testing.assert_allclose(ch.input_matrix(rank_one, 0) @ ch.C[0], rank_one.A[0], atol=1e-14)


@pytest.mark.parametrize(("method", "mu"), [("rcc", None), ("wirtinger", 0.0), ("io", None)])
def test_reduced_bounds_are_sound(rank_one, method, mu):
    exact = exact_constant_margin(rank_one)
    h = max_delay(rank_one, method, mu)
    assert 0 < h <= exact


def test_reduced_problem_is_smaller_and_dpp(rank_one):
    problem = LMIProblem(PolytopicDelaySystem((rank_one,)), METHODS["rcc"], None)
    assert problem.problem.is_dcp(dpp=True)
    sizes = [c.args[0].shape[0] for c in problem.problem.constraints if c.args[0].ndim == 2]
    # x, dx and two 1-dimensional delayed signals, less the kinematic row x1' = x2
    assert max(sizes) == 2 * 3 + 2 * 1 - 1
    assert max_delay_certificate(rank_one, "rcc").eliminated == (0,)


def test_certificate_channels_round_trip_and_tamper(rank_one):
    cert = max_delay_certificate(rank_one, "rcc")
    assert cert.certified and cert.verify()
    assert len(cert.channels) == 1 and cert.channels[0].shape == (1, 3)
    back = type(cert).from_json(cert.to_json())
    assert back.verify()
    rotated = dataclasses.replace(cert, channels=(np.array([[0.0, 1.0, 0.0]]),))
    assert not rotated.verify()
