"""Properties of the planar-arm dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.model.dynamics import (
    coriolis_matrix,
    kinetic_energy,
    mass_matrix,
    mass_matrix_derivative,
)
from teleopkit.model.params import PlanarArm

ARMS = [PlanarArm(), PlanarArm((0.3, 0.25, 0.2, 0.15), (0.6, 0.4, 0.3, 0.2)),
        PlanarArm((0.38, 0.38), (0.5, 0.35), com=(0.19, 0.25), inertia=(0.006, 0.004)),
        PlanarArm((0.3, 0.25, 0.2), (0.6, 0.4, 0.3), com=(0.0, 0.3, 0.1),
                  inertia=(0.01, 0.0, 0.002))]
"""Point masses (the paper's and four links), then links with centres of mass and inertias."""


@pytest.mark.parametrize("arm", ARMS)
def test_mass_matrix_symmetric_positive_definite(arm, rng):
    q = rng.uniform(-np.pi, np.pi, size=(200, arm.n_joints))
    m = mass_matrix(arm, q)
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2), atol=1e-14)
    assert np.linalg.eigvalsh(m).min() > 0


def test_two_link_matches_paper_closed_form(params, rng):
    arm = params.local_arm
    (l1, l2), (m1, m2) = arm.lengths, arm.masses
    q = rng.uniform(-np.pi, np.pi, size=(50, 2))
    dq = rng.normal(size=(50, 2))
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    m11 = l2**2 * m2 + l1**2 * (m1 + m2) + 2 * l1 * l2 * m2 * c2
    m12 = l2**2 * m2 + l1 * l2 * m2 * c2
    expected_m = np.stack([np.stack([m11, m12], -1),
                           np.stack([m12, np.full_like(m12, l2**2 * m2)], -1)], -2)
    beta = l1 * l2 * m2
    expected_c = beta * s2[:, None, None] * np.stack([
        np.stack([-dq[:, 1], -(dq[:, 0] + dq[:, 1])], -1),
        np.stack([dq[:, 0], np.zeros(50)], -1)], -2)
    np.testing.assert_allclose(mass_matrix(arm, q), expected_m, atol=1e-14)
    np.testing.assert_allclose(coriolis_matrix(arm, q, dq), expected_c, atol=1e-14)


@pytest.mark.parametrize("arm", ARMS)
def test_mdot_minus_2c_is_skew_symmetric(arm, rng):
    q = rng.uniform(-np.pi, np.pi, size=(200, arm.n_joints))
    dq = rng.normal(scale=3.0, size=q.shape)
    n_matrix = mass_matrix_derivative(arm, q, dq) - 2 * coriolis_matrix(arm, q, dq)
    np.testing.assert_allclose(n_matrix, -np.swapaxes(n_matrix, -1, -2), atol=1e-12)
    assert np.abs(n_matrix).max() > 1e-3  # the property is not met trivially


@pytest.mark.parametrize("arm", ARMS)
def test_mass_matrix_derivative_matches_finite_difference(arm, rng):
    q = rng.uniform(-np.pi, np.pi, size=(20, arm.n_joints))
    dq = rng.normal(size=q.shape)
    eps = 1e-6
    numeric = (mass_matrix(arm, q + eps * dq) - mass_matrix(arm, q - eps * dq)) / (2 * eps)
    np.testing.assert_allclose(mass_matrix_derivative(arm, q, dq), numeric, atol=1e-8)


@pytest.mark.parametrize("arm", ARMS[1:])
def test_coriolis_is_the_lagrangian_term(arm, rng):
    """C q' equals M' q' - dT/dq from the Lagrangian, by finite differences."""
    q = rng.uniform(-np.pi, np.pi, size=arm.n_joints)
    dq = rng.normal(size=arm.n_joints)
    eps = 1e-6
    grad = np.array([(kinetic_energy(arm, q + eps * e, dq) - kinetic_energy(arm, q - eps * e, dq))
                     / (2 * eps) for e in np.eye(arm.n_joints)])
    expected = mass_matrix_derivative(arm, q, dq) @ dq - grad
    np.testing.assert_allclose(coriolis_matrix(arm, q, dq) @ dq, expected, atol=1e-8)
