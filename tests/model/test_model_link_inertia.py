"""Links with a centre of mass and an inertia of their own: dynamics, records and energy."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from teleopkit import ConstantDelay, Scenario, Simulator
from teleopkit.model.dynamics import (
    coriolis_matrix,
    inertia_coefficients,
    kinetic_energy,
    mass_matrix,
)
from teleopkit.model.params import (
    ElasticJoints,
    InitialState,
    Operator,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    one_joint_setup,
    paper_setup,
)
from teleopkit.model.records import plant_mismatch, plant_params, plant_record
from teleopkit.sim.energy import local_energy, remote_energy

PAPER_FINGERPRINT = "83e859b5b4c6dae9"
"""``plant_record(paper_setup())["fingerprint"]`` before arms had a centre of mass and an inertia
(shipped certificates and policies store it)."""

ONE_JOINT_FINGERPRINT = "f7e3ef8a6ff604d8"
"""The same for :func:`one_joint_setup`."""

ROD = PlanarArm((0.38, 0.38), (0.5, 0.35), com=(0.19, 0.19),
                inertia=(0.5 * 0.38**2 / 12, 0.35 * 0.38**2 / 12))
"""The paper's arm made of uniform rods."""


def _random_arm(rng: np.random.Generator, n: int) -> PlanarArm:
    lengths = rng.uniform(0.2, 0.5, n)
    return PlanarArm(tuple(lengths), tuple(rng.uniform(0.2, 1.0, n)),
                     com=tuple(lengths * rng.uniform(0.05, 1.3, n)),
                     inertia=tuple(rng.uniform(0.0, 0.05, n)))


def _centres_of_mass(arm: PlanarArm, q: np.ndarray) -> np.ndarray:
    """Plane positions ``(..., n, 2)`` of the links' centres of mass."""
    phi = np.cumsum(q, axis=-1)
    direction = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    joints = np.cumsum(np.array(arm.lengths)[:, None] * direction, axis=-2) - (
        np.array(arm.lengths)[:, None] * direction)
    return joints + np.array(arm.centres)[:, None] * direction


def _reference_kinetic_energy(arm: PlanarArm, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """``sum_i m_i |p_i'|^2 / 2 + I_i phi_i'^2 / 2``, velocities by central differences."""
    eps = 1e-6
    velocity = (_centres_of_mass(arm, q + eps * dq) - _centres_of_mass(arm, q - eps * dq)) / (
        2 * eps)
    translation = 0.5 * np.sum(np.array(arm.masses) * np.sum(velocity**2, axis=-1), axis=-1)
    spin = 0.5 * np.sum(np.array(arm.link_inertias) * np.cumsum(dq, axis=-1) ** 2, axis=-1)
    return translation + spin


@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_kinetic_energy_of_the_centres_of_mass(n, seed):
    rng = np.random.default_rng(seed)
    arm = _random_arm(rng, n)
    q = rng.uniform(-np.pi, np.pi, size=(100, n))
    dq = rng.normal(scale=2.0, size=q.shape)
    np.testing.assert_allclose(kinetic_energy(arm, q, dq), _reference_kinetic_energy(arm, q, dq),
                               rtol=1e-8)


def test_two_link_closed_form_with_centres_and_inertias(rng):
    (l1, _), (m1, m2), (c1, c2), (i1, i2) = ROD.lengths, ROD.masses, ROD.centres, ROD.link_inertias
    a11, a12, a22 = m1 * c1**2 + i1 + l1**2 * m2, l1 * c2 * m2, m2 * c2**2 + i2
    q = rng.uniform(-np.pi, np.pi, size=(50, 2))
    dq = rng.normal(size=(50, 2))
    c, s = np.cos(q[:, 1]), np.sin(q[:, 1])
    m12 = a22 + a12 * c
    expected_m = np.stack([np.stack([a11 + a22 + 2 * a12 * c, m12], -1),
                           np.stack([m12, np.full_like(c, a22)], -1)], -2)
    expected_c = a12 * s[:, None, None] * np.stack([
        np.stack([-dq[:, 1], -(dq[:, 0] + dq[:, 1])], -1),
        np.stack([dq[:, 0], np.zeros(50)], -1)], -2)
    np.testing.assert_allclose(mass_matrix(ROD, q), expected_m, atol=1e-15)
    np.testing.assert_allclose(coriolis_matrix(ROD, q, dq), expected_c, atol=1e-15)


@pytest.mark.parametrize("arm", [PlanarArm(), PlanarArm((0.3, 0.25, 0.2, 0.15),
                                                        (0.6, 0.4, 0.3, 0.2))])
def test_point_masses_keep_their_coefficients_bit_for_bit(arm):
    lengths = np.array(arm.lengths)
    outboard = np.cumsum(np.array(arm.masses)[::-1])[::-1]
    index = np.arange(arm.n_joints)
    before = np.outer(lengths, lengths) * outboard[np.maximum.outer(index, index)]
    np.testing.assert_array_equal(inertia_coefficients(arm), before)
    explicit = PlanarArm(arm.lengths, arm.masses, com=arm.lengths, inertia=0.0)
    assert explicit == arm and explicit.com is None and explicit.inertia is None
    np.testing.assert_array_equal(inertia_coefficients(explicit), before)


def test_point_mass_records_keep_their_fingerprints():
    record = plant_record(paper_setup())
    assert record["fingerprint"] == PAPER_FINGERPRINT
    assert set(record["local_arm"]) == set(record["remote_arm"]) == {"lengths", "masses"}
    assert plant_record(one_joint_setup())["fingerprint"] == ONE_JOINT_FINGERPRINT
    assert plant_params(record).local_arm == paper_setup().local_arm


def test_records_with_centres_and_inertias_round_trip():
    params = TeleoperatorParams(remote_arm=ROD)
    record = json.loads(json.dumps(plant_record(params)))
    assert record["remote_arm"]["com"] == [0.19, 0.19] and "com" not in record["local_arm"]
    assert record["fingerprint"] != PAPER_FINGERPRINT
    rebuilt = plant_params(record)
    assert rebuilt.remote_arm == ROD and rebuilt.local_arm == PlanarArm()
    assert plant_record(rebuilt)["fingerprint"] == record["fingerprint"]
    assert plant_mismatch(record, rebuilt) is None
    message = plant_mismatch(plant_record(paper_setup()), params)
    assert message is not None and "remote arm centres of mass" in message


def test_properties_are_always_tuples():
    arm = PlanarArm((0.3, 0.2), (1.0, 0.5), com=0.1)
    assert arm.centres == (0.1, 0.1) and arm.link_inertias == (0.0, 0.0)
    assert PlanarArm().centres == (0.38, 0.38) and PlanarArm().link_inertias == (0.0, 0.0)
    assert PlanarArm((0.3, 0.2), (1.0, 0.5), inertia=(0.0, 0.01)).inertia == (0.0, 0.01)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"com": (0.1, 0.2, 0.3)}, "^arm lengths and arm com need one per joint, got 2 and 3 values$"),
    ({"com": (0.1, -0.2)}, "^arm com must be non-negative"),
    ({"com": (0.1, math.nan)}, "^arm com must be finite"),
    ({"com": (0.1, math.inf)}, "^arm com must be finite"),
    ({"inertia": (0.01,)}, "^arm lengths and arm inertia need one per joint, got 2 and 1 values$"),
    ({"inertia": (0.01, -1e-3)}, "^arm inertia must be non-negative"),
    ({"inertia": (math.nan, 0.0)}, "^arm inertia must be finite"),
    ({"com": (0.2, 0.0)}, r"^arm com or inertia must be positive on every link, links \[2\]"),
    ({"com": 0.0, "inertia": (0.01, 0.0)}, r"links \[2\]"),
])
def test_bad_centres_and_inertias_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        PlanarArm((0.38, 0.38), (0.5, 0.35), **kwargs)
    assert "\n" not in str(error.value)


def test_a_centre_at_the_joint_with_an_inertia_is_fine():
    arm = PlanarArm((0.38, 0.38), (0.5, 0.35), com=(0.0, 0.0), inertia=(0.01, 0.01))
    q = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(200, 2))
    assert np.linalg.eigvalsh(mass_matrix(arm, q)).min() > 0


def _free_teleoperator(arm: PlanarArm, local: tuple[float, ...]) -> TeleoperatorParams:
    """Both arms ``arm``, no control, the operator a lossless spring to the origin."""
    n = arm.n_joints
    return TeleoperatorParams(
        local_arm=arm, remote_arm=arm, joints=ElasticJoints((100.0,) * n, (0.3,) * n),
        local_gains=PDGains.uniform(0.0, 0.0, n), remote_gains=PDGains.uniform(0.0, 0.0, n),
        operator=Operator(stiffness=10.0, damping=0.0, amplitudes=(0.0,) * n,
                          frequencies=(1.0,) * n, phases=(0.0,) * n, decays=(0.0,) * n),
        initial=InitialState(local, (0.0,) * n, (-0.4,) * n), torque_limit=math.inf)


@pytest.mark.parametrize(("arm", "local"), [
    (ROD, (-0.6, 0.9)),
    (PlanarArm((0.3, 0.25, 0.2), (0.6, 0.4, 0.3), com=(0.1, 0.2, 0.05),
               inertia=(0.004, 0.0, 0.002)), (-0.6, 0.9, 0.5)),
])
@pytest.mark.parametrize(("backend", "duration"), [("compiled", 2.0), ("numpy", 0.3)])
def test_uncontrolled_arms_with_link_inertia_conserve_energy(arm, local, backend, duration):
    params = _free_teleoperator(arm, local)
    n = arm.n_joints
    scenario = Scenario(params, ConstantDelay(0.0), ConstantDelay(0.0), np.ones((1, n)))
    trajectory = Simulator(scenario, dt=0.00025, control_period=0.01, backend=backend).run(
        duration, np.zeros(2 * n))
    state = trajectory.state[:, 0]
    energies = {"local": local_energy(params, state), "remote": remote_energy(params, state)}
    for energy in energies.values():
        assert energy[0] > 0.1  # springs start stretched: there is energy to conserve
        assert np.abs(energy / energy[0] - 1).max() < 1e-6
    moved = np.abs(np.diff(state[:, :n], axis=0)).sum(axis=0)  # q_l travels on every joint
    assert moved.min() > 0.1


def test_compiled_kernel_matches_numpy_with_link_inertia(rng):
    arm = _random_arm(rng, 3)
    params = _free_teleoperator(arm, (-0.6, 0.9, 0.5))
    scenario = Scenario(params, ConstantDelay(0.02), ConstantDelay(0.03), np.ones((2, 3)))
    gains = rng.uniform(1.0, 30.0, size=(10, 2, 6))
    runs = [Simulator(scenario, dt=0.0005, backend=b).advance(gains) for b in ("compiled", "numpy")]
    np.testing.assert_allclose(runs[0].state, runs[1].state, rtol=0, atol=1e-10)
