"""The linearisation at rest matches finite differences of the nonlinear closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.model.dynamics import mass_matrix
from teleopkit.model.laws import local_torque, operator_torque, remote_torque
from teleopkit.model.linearize import (
    inertia_vertices,
    linearized_state_space,
    linearized_system,
    rest_systems,
)
from teleopkit.model.params import paper_setup


def _nonlinear(params, gains, x, ql_delayed, th_delayed):
    """E-scaled right-hand side at rest-level accuracy: returns E(q) x' without Coriolis terms,
    which vanish to first order at zero velocity."""
    n = params.n_joints
    ql, dql, qr, dqr, th, dth = np.split(x, 6)
    tau_h = operator_torque(params.operator, np.zeros(n), ql, dql)
    tau_l = local_torque(params.local_gains, ql, dql, th_delayed)
    tau_r = remote_torque(gains, th, dth, ql_delayed)
    spring = np.array(params.joints.stiffness) * (qr - th)
    return np.concatenate([dql, tau_h - tau_l, dqr, -spring, dth, tau_r + spring])


@pytest.mark.parametrize("q2", [0.0, np.pi])
def test_linearization_matches_finite_differences(q2):
    params = paper_setup()
    gains = np.array([12.0, 8.0, 30.0, 25.0])
    n = params.n_joints
    rest = np.zeros(6 * n)
    rest[1] = rest[2 * n + 1] = q2  # configuration with cos q2 = +-1 on both arms
    eps = 1e-6
    columns = []
    for e in np.eye(6 * n):
        plus = _nonlinear(params, gains, rest + eps * e, rest[:n], rest[4 * n:5 * n])
        minus = _nonlinear(params, gains, rest - eps * e, rest[:n], rest[4 * n:5 * n])
        columns.append((plus - minus) / (2 * eps))
    a0 = np.array(columns).T
    masses = [mass_matrix(arm, np.array([0.0, q2])) for arm in (params.local_arm,
                                                                params.remote_arm)]
    system = linearized_system(params, gains[:n], gains[n:], *masses)
    np.testing.assert_allclose(system.A0, a0, atol=1e-6)
    forward, backward = system.A
    assert np.array_equal(forward[5 * n:, :n], np.diag(gains[:n]))
    assert np.array_equal(backward[n:2 * n, 4 * n:5 * n], np.diag(params.local_gains.stiffness))
    assert np.count_nonzero(forward) == n and np.count_nonzero(backward) == n
    np.testing.assert_allclose(system.E[n:2 * n, n:2 * n], masses[0])


def test_inertia_vertices_bound_every_configuration(rng):
    arm = paper_setup().local_arm
    low, high = inertia_vertices(arm)
    for q in rng.uniform(-np.pi, np.pi, size=(50, 2)):
        m = mass_matrix(arm, q)
        weight = (np.cos(q[1]) + 1) / 2
        np.testing.assert_allclose(m, (1 - weight) * low + weight * high, atol=1e-14)


def test_state_space_is_stable_and_tracks_at_dc():
    params = paper_setup()
    sys = linearized_state_space(params, 10.0, 30.0)
    assert sys.nstates == 12 and sys.ninputs == 2 and sys.noutputs == 4
    assert np.real(sys.poles()).max() < 0
    dc = sys.dcgain()
    np.testing.assert_allclose(dc[2:], 0.0, atol=1e-12)  # no static flexibility error
    with pytest.raises(ValueError, match="cos_q"):
        linearized_state_space(params, 10.0, 30.0, cos_q=2.0)


def test_rest_systems_share_the_configuration_on_both_arms():
    params = paper_setup()
    action = np.array([12.0, 8.0, 30.0, 25.0])
    systems = rest_systems(params, action)
    assert len(systems) == 2
    n = params.n_joints
    for system, q2 in zip(systems, (np.pi, 0.0), strict=True):
        q = np.array([0.0, q2])
        np.testing.assert_allclose(system.E[n:2 * n, n:2 * n], mass_matrix(params.local_arm, q))
        np.testing.assert_allclose(system.E[3 * n:4 * n, 3 * n:4 * n],
                                   mass_matrix(params.remote_arm, q))
