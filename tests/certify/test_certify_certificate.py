from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from certify import Certificate, certify_delay, max_delay_certificate


@pytest.fixture(scope="module")
def certificate(benchmark_system) -> Certificate:
    return max_delay_certificate(benchmark_system, "wirtinger", mu=0.0)


def test_certificate_content(certificate):
    assert certificate.certified
    assert certificate.method == "wirtinger"
    assert certificate.mu == 0.0
    assert certificate.margin == pytest.approx(6.059, rel=0.02)
    assert certificate.delay_bounds == (certificate.margin,)
    assert certificate.solver == "CLARABEL" and certificate.status == "optimal"
    assert any("constant" in a for a in certificate.assumptions)
    assert {"P", "Q0", "R0", "N0"} <= set(certificate.matrices)
    assert min(certificate.residuals.values()) > 0


def test_verify_and_json_round_trip(certificate):
    assert certificate.verify()
    text = certificate.to_json()
    data = json.loads(text)
    assert isinstance(data["matrices"]["P"], list)
    back = Certificate.from_json(text)
    assert back.verify()
    assert back.to_json() == text
    for key, value in certificate.matrices.items():
        np.testing.assert_array_equal(back.matrices[key], value)


@pytest.mark.parametrize(
    "tamper",
    [
        lambda m: {**m, "P": -m["P"]},
        lambda m: {**m, "R0": m["R0"] * 0.0},
        lambda m: {**m, "N0": m["N0"] * 1.5},
        lambda m: {k: v for k, v in m.items() if k != "Q0"},
        lambda m: {**m, "P": m["P"] + np.triu(np.ones_like(m["P"]), 1)},
        lambda m: {**m, "U0": np.eye(2)},
    ],
)
def test_verify_rejects_tampered_matrices(certificate, tamper):
    bad = dataclasses.replace(certificate, matrices=tamper(dict(certificate.matrices)))
    assert not bad.verify()


def test_verify_rejects_larger_delay_bound(certificate):
    bigger = dataclasses.replace(certificate, delay_bounds=(1.2 * certificate.delay_bounds[0],))
    assert not bigger.verify()


def test_verify_rejects_changed_delay_class(certificate):
    assert not dataclasses.replace(certificate, mu=None).verify()
    assert not dataclasses.replace(certificate, method="jensen").verify()


def test_uncertified_result_does_not_verify(benchmark_system):
    cert = certify_delay(benchmark_system, 3.0, "jensen")
    assert not cert.certified and not cert.verify()
    assert Certificate.from_json(cert.to_json()).certified is False


def test_fast_varying_assumptions(benchmark_system):
    cert = certify_delay(benchmark_system, 0.9, "io")
    assert cert.certified and cert.verify()
    assert any("unknown derivative" in a for a in cert.assumptions)
