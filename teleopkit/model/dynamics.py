"""Rigid-body dynamics of planar serial arms (numpy, batched).

Link ``i`` has length ``l_i``, mass ``m_i`` at the distance ``c_i`` from its joint and the
inertia ``I_i`` about its centre of mass (:class:`~teleopkit.model.params.PlanarArm`; the paper's
point masses at the tips are ``c = l``, ``I = 0``). With absolute link angles ``phi = T q``
(``T`` lower-triangular ones) the inertia is ``M(q) = T^T M_abs T`` with
``M_abs[i, j] = a_ij cos(phi_i - phi_j)`` and the coefficients

- ``a_ii = m_i c_i^2 + I_i + l_i^2 sum_{k > i} m_k``,
- ``a_ij = a_ji = l_i (m_j c_j + l_j sum_{k > j} m_k)`` for ``i < j``,

which for point masses are ``a_ij = l_i l_j sum_{k >= max(i, j)} m_k``. The Coriolis matrix
``C = T^T C_abs T`` with ``C_abs[i, j] = a_ij sin(phi_i - phi_j) phi_j'`` makes ``M' - 2C``
skew-symmetric: the diagonal ``a_ii`` is constant, so ``M_abs' - 2 C_abs`` is
``-a_ij sin(phi_i - phi_j) (phi_i' + phi_j')``, antisymmetric. For two links this is
``M11 = a11 + a22 + 2 a12 cos q2``, ``M12 = a22 + a12 cos q2``, ``M22 = a22`` and
``C = beta sin q2 [[-q2', -(q1' + q2')], [q1', 0]]`` with ``beta = a12 = l1 c2 m2``; the paper's
``M11 = l2^2 m2 + l1^2 (m1 + m2) + 2 l1 l2 m2 cos q2`` and ``beta = l1 l2 m2`` for point masses.

All functions accept any leading batch axes: ``q`` has shape ``(..., n)``.
"""

from __future__ import annotations

import numpy as np

from teleopkit.model.params import ElasticJoints, PlanarArm

__all__ = [
    "coriolis_matrix",
    "elastic_arm_energy",
    "inertia_coefficients",
    "kinetic_energy",
    "mass_from_coefficients",
    "mass_from_cosines",
    "mass_matrix",
    "mass_matrix_derivative",
]


def inertia_coefficients(arm: PlanarArm) -> np.ndarray:
    """Return the inertia coefficients ``a_ij`` of ``M_abs[i, j] = a_ij cos(phi_i - phi_j)``.

    They are the point-mass coefficients ``l_i l_j sum_{k >= max(i, j)} m_k`` plus what each
    link's own mass distribution changes: ``m_i (c_i^2 - l_i^2) + I_i`` on the diagonal and
    ``l_i m_j (c_j - l_j)`` for ``i < j`` (zero for point masses at the tips, so that those
    coefficients keep their bits).

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry, masses, centres of mass and link inertias.

    Returns
    -------
    ndarray, shape (n, n)
        Symmetric coefficients ``a_ij`` in kg m^2.
    """
    lengths, masses = np.array(arm.lengths), np.array(arm.masses)
    centres = np.array(arm.centres)
    outboard = np.cumsum(masses[::-1])[::-1]
    index = np.arange(arm.n_joints)
    point = np.outer(lengths, lengths) * outboard[np.maximum.outer(index, index)]
    shift = np.triu(np.outer(lengths, masses * (centres - lengths)), 1)
    own = masses * (centres**2 - lengths**2) + np.array(arm.link_inertias)
    return point + shift + shift.T + np.diag(own)


def _absolute(q: np.ndarray) -> np.ndarray:
    return np.cumsum(q, axis=-1)


def _relative_sines(q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(phi_i - phi_j)`` ``(..., n, n)`` and the absolute link rates ``phi'`` ``(..., n)``."""
    phi = _absolute(np.asarray(q, dtype=float))
    return np.sin(phi[..., :, None] - phi[..., None, :]), _absolute(np.asarray(dq, dtype=float))


def _to_joint(matrix_abs: np.ndarray) -> np.ndarray:
    """Map ``X_abs`` to ``T^T X_abs T`` (suffix sums over both axes)."""
    suffix_rows = np.flip(np.cumsum(np.flip(matrix_abs, -2), -2), -2)
    return np.flip(np.cumsum(np.flip(suffix_rows, -1), -1), -1)


def mass_matrix(arm: PlanarArm, q: np.ndarray) -> np.ndarray:
    """Inertia matrix ``M(q)``.

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry and masses.
    q : ndarray, shape (..., n)
        Joint angles.

    Returns
    -------
    ndarray, shape (..., n, n)
        Symmetric positive definite inertia matrix.
    """
    return mass_from_coefficients(inertia_coefficients(arm), q)


def mass_from_coefficients(coefficients: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Inertia matrix ``M(q)`` from the arm's :func:`inertia_coefficients`.

    Parameters
    ----------
    coefficients : ndarray, shape (n, n) or (..., n, n)
        Inertia coefficients: one arm's, or one per entry of a batch of arms.
    q : ndarray, shape (..., n)
        Joint angles.

    Returns
    -------
    ndarray, shape (..., n, n)
        Symmetric positive definite inertia matrix.
    """
    phi = _absolute(np.asarray(q, dtype=float))
    return _to_joint(coefficients * np.cos(phi[..., :, None] - phi[..., None, :]))


def mass_from_cosines(arm: PlanarArm, cosines: np.ndarray) -> np.ndarray:
    """Inertia matrix from the cosines ``cos(phi_i - phi_j)`` of the relative link angles.

    ``M`` is affine in these cosines, which is what makes inertia polytopes exact.

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry and masses.
    cosines : ndarray, shape (..., n, n)
        Symmetric matrix of cosines with ones on the diagonal.

    Returns
    -------
    ndarray, shape (..., n, n)
        The inertia matrix.
    """
    return _to_joint(inertia_coefficients(arm) * cosines)


def coriolis_matrix(arm: PlanarArm, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Coriolis and centrifugal matrix ``C(q, q')`` with ``M' - 2C`` skew-symmetric.

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry and masses.
    q, dq : ndarray, shape (..., n)
        Joint angles and velocities.

    Returns
    -------
    ndarray, shape (..., n, n)
        The matrix ``C``; the Coriolis torque is ``C @ dq``.
    """
    sines, dphi = _relative_sines(q, dq)
    return _to_joint(inertia_coefficients(arm) * sines * dphi[..., None, :])


def mass_matrix_derivative(arm: PlanarArm, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Time derivative ``dM/dt`` of the inertia matrix along the motion ``(q, q')``.

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry and masses.
    q, dq : ndarray, shape (..., n)
        Joint angles and velocities.

    Returns
    -------
    ndarray, shape (..., n, n)
        The symmetric matrix ``M'``; ``M' - 2C`` is skew-symmetric (:func:`coriolis_matrix`).
    """
    sines, dphi = _relative_sines(q, dq)
    return _to_joint(-inertia_coefficients(arm) * sines * (dphi[..., :, None] - dphi[..., None, :]))


def kinetic_energy(arm: PlanarArm, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Kinetic energy ``q'^T M(q) q' / 2`` of the arm.

    Parameters
    ----------
    arm : PlanarArm
        Arm geometry and masses.
    q, dq : ndarray, shape (..., n)
        Joint angles and velocities.

    Returns
    -------
    ndarray, shape (...)
        Kinetic energy in joules.
    """
    dq = np.asarray(dq, dtype=float)
    return 0.5 * np.einsum("...i,...ij,...j->...", dq, mass_matrix(arm, q), dq)


def elastic_arm_energy(arm: PlanarArm, joints: ElasticJoints, q: np.ndarray, dq: np.ndarray,
                  theta: np.ndarray, dtheta: np.ndarray) -> np.ndarray:
    """Stored energy of the elastic remote arm: link and rotor kinetic energy plus spring energy.

    Parameters
    ----------
    arm : PlanarArm
        Link side of the remote arm.
    joints : ElasticJoints
        Joint stiffness and rotor inertia.
    q, dq : ndarray, shape (..., n)
        Link angles and velocities.
    theta, dtheta : ndarray, shape (..., n)
        Motor angles and velocities.

    Returns
    -------
    ndarray, shape (...)
        ``q'^T M q' / 2 + theta'^T J theta' / 2 + (q - theta)^T S (q - theta) / 2``.
    """
    stretch = np.asarray(q) - np.asarray(theta)
    rotor = 0.5 * np.sum(np.array(joints.rotor_inertia) * np.asarray(dtheta) ** 2, axis=-1)
    spring = 0.5 * np.sum(np.array(joints.stiffness) * stretch**2, axis=-1)
    return kinetic_energy(arm, q, dq) + rotor + spring
