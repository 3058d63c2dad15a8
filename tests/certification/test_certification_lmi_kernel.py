"""The LMIs of a teleoperator cell are posed on the kernel of its kinematic rows, soundly.

Eliminating the rows ``q' = v`` of the descriptor relation shrinks every derivative condition;
the tests check that this is the Finsler elimination it claims to be: a solution on the kernel
extends to a solution of the full conditions, with the slack ``-s Gamma_c^T`` on those rows.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from certify import Certificate
from certify.channels import Channels
from certify.check import residuals, variables_valid
from certify.methods import get_method
from certify.system_data import eliminable_rows, relation_kernel, system_data
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.systems import gain_set_system, lmi_certificate

CELL = GainPolytope.from_box(GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1))
BOUND = 1.2


@pytest.fixture(scope="module")
def certificate(one_joint) -> Certificate:
    cert = lmi_certificate(one_joint, CELL, BOUND, BOUND, variation="switching")
    assert cert.certified and cert.verify()
    return cert


def _posed(cert: Certificate):
    """The method, system and channels the certificate's matrices refer to."""
    method = get_method(cert.method)
    system = cert.system.scaled(cert.scaling) if cert.scaling else cert.system
    return method, system, Channels(system.n, tuple(cert.channels))


def test_the_kinematic_rows_are_eliminated(one_joint, certificate):
    system = gain_set_system(one_joint, CELL, "switching")
    method, _, ch = _posed(certificate)
    full = system_data(method, system, ch, certificate.mu, eliminated=())
    rows = eliminable_rows(full.relations, full.left, ch.n)
    assert certificate.eliminated == rows and len(rows) == ch.n // 2  # one q' = v per coordinate
    kernel = relation_kernel(full.relations, full.left, ch.n, rows)
    for relation in full.relations:
        np.testing.assert_allclose(relation[list(rows)] @ kernel, 0.0, atol=1e-12)
    assert np.linalg.matrix_rank(kernel) == kernel.shape[1] == kernel.shape[0] - len(rows)


def test_a_row_that_mixes_states_cannot_be_eliminated(one_joint, certificate):
    system = gain_set_system(one_joint, CELL, "switching")
    method, _, ch = _posed(certificate)
    full = system_data(method, system, ch, certificate.mu, eliminated=())
    dynamic = next(r for r in range(ch.n) if r not in certificate.eliminated)
    for rows in ((dynamic,), (ch.n,), (certificate.eliminated[0],) * 2):
        with pytest.raises(ValueError, match="cannot be eliminated"):
            relation_kernel(full.relations, full.left, ch.n, rows)


def test_the_kernel_solution_extends_to_the_full_conditions(certificate):
    """Finsler's lemma, constructively: ``N = [Z (Z^T Z)^-1 N_r, -s Gamma_c^T]`` for large s."""
    method, system, ch = _posed(certificate)
    reduced = system_data(method, system, ch, certificate.mu, certificate.eliminated)
    full = system_data(method, system, ch, certificate.mu, eliminated=())
    rows = list(certificate.eliminated)
    kept = np.setdiff1d(np.arange(ch.n), rows)
    kinematic = full.relations[0][rows]
    lift = reduced.kernel @ np.linalg.inv(reduced.kernel.T @ reduced.kernel)
    best = -np.inf
    for s in np.logspace(0, 8, 17):
        matrices = dict(certificate.matrices)
        for name, slack in certificate.matrices.items():
            if name.startswith("N"):
                wide = np.zeros((full.slack_shape[0], ch.n))
                wide[:, kept], wide[:, rows] = lift @ slack, -s * kinematic.T
                matrices[name] = wide
        assert variables_valid(method, system, ch, certificate.mu, matrices, full)
        res = residuals(method, system, ch, matrices, certificate.delay_bounds, certificate.mu,
                        full)
        best = max(best, min(res.values()))
    assert best > 0


def test_eliminated_rows_are_part_of_what_is_verified(certificate):
    back = Certificate.from_json(certificate.to_json())
    assert back.eliminated == certificate.eliminated and back.verify()
    assert not dataclasses.replace(certificate, eliminated=()).verify()  # slacks no longer fit
    dynamic = next(r for r in range(4) if r not in certificate.eliminated)
    claimed = (*certificate.eliminated[:-1], dynamic)
    assert not dataclasses.replace(certificate, eliminated=claimed).verify()


def test_a_proof_of_the_full_relation_still_verifies(one_joint, monkeypatch):
    """A certificate written before the elimination (no ``eliminated`` key) keeps verifying."""
    monkeypatch.setattr("certify.system_data.eliminable_rows", lambda *args: ())
    full = lmi_certificate(one_joint, CELL, BOUND, BOUND, variation="switching")
    assert full.certified and full.eliminated == ()
    record = full.to_dict()
    del record["eliminated"]
    assert Certificate.from_dict(record).verify()
