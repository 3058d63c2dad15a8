"""Tests of teleopkit.rl.torch_projection: the safety layer's projection in torch."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scheduled_helpers import PASSIVE, adversarial, certified
from test_rl_td3 import ACT

from teleopkit.rl.torch_projection import TorchProjection, torch_projection
from teleopkit.safety import CertifiedLoop
from teleopkit.safety.factory import layer_for


def test_torch_projection_matches_the_safety_layer(layer):
    projection = TorchProjection(layer.polytope)
    rng = np.random.default_rng(3)
    raw = np.concatenate([rng.uniform(-100, 300, (4000, ACT)),
                          layer.polytope.vertices() + rng.normal(0, 1e-3, (16, ACT)),
                          rng.uniform(1e3, 1e6, (50, ACT)) * rng.choice([-1, 1], (50, ACT))])
    expected = layer.project_batch(raw).action
    got = projection(torch.as_tensor(raw)).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-9)
    single = projection(torch.as_tensor(raw, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(single, expected, rtol=1e-5, atol=1e-3)


def test_projection_gradient_is_identity_inside_and_tangent_on_an_edge(layer):
    projection = TorchProjection(layer.polytope)
    inside = torch.tensor([[10.0, 10.0, 60.0, 60.0]], dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(projection, inside)[0, :, 0, :]
    np.testing.assert_allclose(jac.numpy(), np.eye(ACT))
    # joint 1 beyond the closed-form edge B = 2.5 K (+ slack), joint 2 inside
    point = torch.tensor([[40.0, 10.0, 60.0, 60.0]], dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(projection, point)[0, :, 0, :].numpy()
    step = 1e-6
    numeric = np.column_stack([
        (layer.project(point[0].numpy() + step * e).action
         - layer.project(point[0].numpy() - step * e).action) / (2 * step)
        for e in np.eye(ACT)])
    np.testing.assert_allclose(jac, numeric, atol=1e-6)
    block = jac[np.ix_([0, 2], [0, 2])]
    np.testing.assert_allclose(block @ block, block, atol=1e-12)  # a projector of rank 1
    assert np.linalg.matrix_rank(block) == 1


@pytest.mark.parametrize("variation", ["scheduled:0.4", "tank:0.02"])
def test_torch_projection_is_the_layers_projection_at_every_step(variation, rng):
    """The actor is trained through the step's set: floor from the observed run-time state."""
    layer = layer_for(certified(variation))
    loop = CertifiedLoop(layer)
    loop.start(adversarial(PASSIVE, batch=4))
    projection = torch_projection(layer)
    for _ in range(60):
        raw = rng.uniform(-20.0, 200.0, (4, 4))
        state = layer.run_time_state(4)
        obs = torch.as_tensor(np.concatenate([np.zeros((4, 14)), state], axis=1))
        expected = projection(torch.as_tensor(raw), obs).numpy()
        _, applied = loop.step(raw)
        np.testing.assert_allclose(applied.action, expected, rtol=1e-10, atol=1e-9)
