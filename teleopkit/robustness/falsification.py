"""Random falsification: nonlinear runs with adversarial delays and gains inside a certified set.

Evidence, never proof: a batch of scenarios is run with delays switching between ``0`` and the
bound (bang-bang, with a random dwell time) or held at the bound, and with remote gains inside
the certified polytope, either frozen per scenario or jumping to a random vertex every control
period. A scenario counts as diverged by the criterion of :mod:`teleopkit.sim.divergence`.
:mod:`teleopkit.robustness.search` optimises the adversary's choices instead of sampling them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.delays.profiles import ConstantDelay, DelayProfile, SwitchingDelay
from teleopkit.model.params import TeleoperatorParams
from teleopkit.sim.divergence import DIVERGENCE_RADIUS, Divergence, position_magnitude
from teleopkit.sim.scenarios import Scenario, sample_reference_gains
from teleopkit.sim.simulator import Simulator

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
            delays: str = "switching", seed: int = 0,
            divergence_radius: float = DIVERGENCE_RADIUS,
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
    results = [sim.advance(gains[p:p + 100]) for p in range(0, periods, 100)]
    magnitude = np.concatenate([position_magnitude(r.state) for r in results])
    finite = np.all([np.isfinite(r.state).all(axis=(0, 2)) for r in results], axis=0)
    verdict = Divergence(divergence_radius).assess(magnitude, finite, periods * sim.control_period)
    return pd.DataFrame({"max_position": verdict["max_position"], "final_position": magnitude[-1],
                         "growth": verdict["growth"], "diverged": verdict["diverged"]},
                        ).rename_axis("scenario")
