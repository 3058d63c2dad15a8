"""Falsification: nonlinear simulations with adversarial delays and gains inside a certified set.

Evidence, never proof: a batch of scenarios is run with delays switching between ``0`` and the
bound as fast as the control loop (bang-bang) or held at the bound, and with remote gains inside
the certified polytope, either frozen per scenario or jumping to a random vertex every control
period. A scenario counts as diverged if its state becomes non-finite or a position leaves
``divergence_radius``, or if the largest position over the last quarter of the run exceeds that
over the second quarter (growth).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from teleopkit.delays import ConstantDelay, DelayProfile, SwitchingDelay
from teleopkit.gains import GainPolytope
from teleopkit.params import TeleoperatorParams
from teleopkit.scenarios import Scenario, sample_reference_gains
from teleopkit.simulator import Simulator

__all__ = ["falsify", "sample_polytope"]


def sample_polytope(polytope: GainPolytope, rng: np.random.Generator, size: int,
                    vertices_only: bool = False) -> np.ndarray:
    """Random gains inside a product-of-polygons polytope, shape ``(size, 2 n)``.

    Parameters
    ----------
    polytope : GainPolytope
        The set (non-empty).
    rng : numpy.random.Generator
        Random source.
    size : int
        Number of samples.
    vertices_only : bool
        Draw vertices of each joint's polygon instead of interior points (the extreme gains).

    Returns
    -------
    ndarray, shape (size, 2 n)
        Actions ``[K_r..., B_r...]`` inside the set.
    """
    n = polytope.dimension // 2
    out = np.empty((size, 2 * n))
    for i in range(n):
        vertices = polytope.joint_vertices(i)
        if vertices.size == 0:
            raise ValueError(f"the gain set is empty on joint {i + 1}")
        if vertices_only:
            weights = np.eye(len(vertices))[rng.integers(len(vertices), size=size)]
        else:
            weights = rng.dirichlet(np.ones(len(vertices)), size=size)
        out[:, [i, n + i]] = weights @ vertices
    return out


def falsify(params: TeleoperatorParams, polytope: GainPolytope, tl_max: float, tr_max: float,
            batch: int = 64, duration: float = 20.0, switching: bool = True,
            delays: str = "switching", seed: int = 0, divergence_radius: float = 20.0,
            ) -> pd.DataFrame:
    """Run adversarial scenarios inside a certified set and report each one.

    Parameters
    ----------
    params : TeleoperatorParams
        Teleoperator.
    polytope : GainPolytope
        Certified gains.
    tl_max, tr_max : float
        Delay bounds; the delays switch between 0 and these with random dwell times.
    batch : int
        Number of scenarios.
    duration : float
        Seconds per scenario.
    switching : bool
        Gains jump to a random vertex every control period (else frozen interior gains).
    delays : {"switching", "bound"}
        Delays jumping between 0 and the bounds with a random dwell time (10, 50 or 200 ms), or
        constant at the bounds.
    seed : int
        Seed of delays, gains and operator references.
    divergence_radius : float
        Position magnitude (rad) that counts as divergence.

    Returns
    -------
    pandas.DataFrame
        One row per scenario: ``max_position``, ``final_position``, ``growth`` (last-quarter over
        second-quarter peak), ``diverged``.
    """
    rng = np.random.default_rng(seed)
    n = params.n_joints
    if delays == "switching":
        dwell = float(rng.choice([0.01, 0.05, 0.2]))
        forward: DelayProfile = SwitchingDelay(0.0, tl_max, dwell, "extremes", seed, batch)
        backward: DelayProfile = SwitchingDelay(0.0, tr_max, dwell, "extremes", seed + 1, batch)
    elif delays == "bound":
        forward, backward = ConstantDelay(tl_max), ConstantDelay(tr_max)
    else:
        raise ValueError(f"delays must be 'switching' or 'bound', got {delays!r}")
    scenario = Scenario(params, forward, backward, sample_reference_gains(rng, batch, n))
    sim = Simulator(scenario)
    periods = round(duration / sim.control_period)
    if switching:
        gains = sample_polytope(polytope, rng, periods * batch, vertices_only=True)
        gains = gains.reshape(periods, batch, 2 * n)
    else:
        gains = np.broadcast_to(sample_polytope(polytope, rng, batch), (periods, batch, 2 * n))
    chunks = [sim.advance(gains[p:p + 100]).state for p in range(0, periods, 100)]
    positions = np.concatenate([c[..., :6 * n].reshape(*c.shape[:2], 6, n)[:, :, ::2]
                                for c in chunks])
    magnitude = np.nan_to_num(np.abs(positions), nan=np.inf).reshape(periods, batch, -1).max(-1)
    quarter = max(1, periods // 4)
    growth = magnitude[-quarter:].max(axis=0) / magnitude[quarter:2 * quarter].max(axis=0)
    peak = magnitude.max(axis=0)
    return pd.DataFrame({
        "max_position": peak,
        "final_position": magnitude[-1],
        "growth": growth,
        "diverged": (peak > divergence_radius) | ~(growth <= 1.0),
    }).rename_axis("scenario")
