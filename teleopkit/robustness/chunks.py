"""One chunk of a campaign: its scenarios simulated as batches, reduced to result rows.

A chunk holds rows of :meth:`~teleopkit.robustness.spec.CampaignSpec.expand`; the rows that share
a teleoperator (and a controller) run as one batch of the simulator, single-threaded (the Dask
workers provide the parallelism). Fixed gains are applied as they are; a trained policy runs
through the certified loop of the closed-form certificate of the row's teleoperator, like the
environments, and its applied actions outside the certified set are counted.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from teleopkit.certification.certifier import default_certificate
from teleopkit.delays.combinators import scale_delay, stack_delays
from teleopkit.delays.profiles import DelayProfile, TraceDelay
from teleopkit.delays.spec import parse_delay
from teleopkit.model.params import (
    ElasticJoints,
    PDGains,
    PlanarArm,
    TeleoperatorParams,
    paper_setup,
)
from teleopkit.rl.env import FlexTeleopConfig, TeleopBatch
from teleopkit.rl.policy import GainPolicy
from teleopkit.robustness.factors import MODEL_FACTORS
from teleopkit.robustness.spec import reference_gains
from teleopkit.setup import Setup
from teleopkit.sim.divergence import Divergence
from teleopkit.sim.metrics import RunningMetrics
from teleopkit.sim.scenarios import Scenario, sample_reference_gains
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.stability import check_motor_damping, check_step

__all__ = ["METRIC_COLUMNS", "ChunkTask", "check_steps", "plan_chunks", "simulate_chunk"]

METRIC_COLUMNS = ("rms_track", "iae_track", "max_track", "rms_damp", "iae_damp", "max_damp",
                  "max_position", "growth", "diverged", "unsafe_actions", "wall_time")
"""Result columns after the factor columns, the reference gains ``G_i`` and ``delay_bound``.
``unsafe_actions`` counts a policy's applied actions outside the certified set (NaN for fixed
gains, which no safety layer sees)."""


def _delay_pair(spec: str, rng: np.random.Generator,
                traces: Mapping[str, TraceDelay]) -> tuple[DelayProfile, DelayProfile]:
    if spec in traces:
        return traces[spec], traces[spec]
    return parse_delay(spec, rng)


def _model_params(row: Mapping[str, Any] | pd.Series) -> TeleoperatorParams:
    """The paper's teleoperator with the row's model factors."""
    base = paper_setup()
    n = base.n_joints

    def arm(source: PlanarArm, scale: float) -> PlanarArm:
        inertia = None if source.inertia is None else tuple(scale * i for i in source.inertia)
        return replace(source, masses=tuple(scale * m for m in source.masses), inertia=inertia)

    return replace(
        base,
        local_arm=arm(base.local_arm, float(row["local_mass_scale"])),
        remote_arm=arm(base.remote_arm, float(row["remote_mass_scale"])),
        joints=ElasticJoints((float(row["joint_stiffness"]),) * n,
                             (float(row["rotor_inertia"]),) * n),
        local_gains=PDGains.uniform(float(row["kl"]), float(row["bl"]), n))


def check_steps(scenarios: pd.DataFrame, dt: float, control_period: float) -> None:
    """Check, before any simulation, that ``dt`` integrates every plant of a campaign stably.

    Each distinct combination of the model factors is checked for its local arm's damping
    (:func:`teleopkit.sim.stability.check_step`) and, for fixed gains, its largest ``B_r``.

    Parameters
    ----------
    scenarios : DataFrame
        The campaign's rows (:meth:`~teleopkit.robustness.spec.CampaignSpec.expand`).
    dt : float
        Integration step in seconds.
    control_period : float
        Gain hold period in seconds (the message proposes a step that divides it).

    Raises
    ------
    ValueError
        One line naming the plant's factors and the largest stable step or gain.
    """
    for _, rows in scenarios.groupby(list(MODEL_FACTORS), sort=False):
        row = rows.iloc[0]
        params = _model_params(row)
        plant = ", ".join(f"{name}={row[name]:g}" for name in MODEL_FACTORS)
        fixed = rows["br"][rows["controller"] == "fixed"]
        try:
            check_step(params, dt, control_period)
            if len(fixed):
                check_motor_damping(params, dt, fixed.max(), "br", control_period)
        except ValueError as error:
            raise ValueError(f"plant {plant}: {error}") from None


@dataclass(frozen=True)
class ChunkTask:
    """What one Dask task simulates.

    Parameters
    ----------
    chunk : int
        Chunk id.
    rows : pandas.DataFrame
        The chunk's rows of :meth:`~teleopkit.robustness.spec.CampaignSpec.expand`.
    duration, dt, control_period, divergence_radius : float
        Episode settings of the spec.
    policies : mapping of str to GainPolicy
        The trained policies of the chunk's ``policy:`` controllers, keyed by level.
    """

    chunk: int
    rows: pd.DataFrame
    duration: float
    dt: float
    control_period: float
    divergence_radius: float
    policies: Mapping[str, GainPolicy] = field(default_factory=dict)


def _scenario_inputs(row: Mapping[str, Any], n: int, traces: Mapping[str, TraceDelay],
                     ) -> tuple[DelayProfile, DelayProfile, np.ndarray]:
    """Forward and backward delays and reference gains of one row, drawn from its seed."""
    rng = np.random.default_rng(int(row["seed"]))
    drawn = sample_reference_gains(rng, 1, n)[0]
    reference = reference_gains(str(row["reference_gain"]), n, drawn)
    forward, backward = _delay_pair(str(row["delay"]), rng, traces)
    scale = float(row["delay_scale"])
    return scale_delay(forward, scale), scale_delay(backward, scale), reference


def _simulate_group(task: ChunkTask, rows: pd.DataFrame,
                    traces: Mapping[str, TraceDelay]) -> pd.DataFrame:
    """Simulate scenarios sharing one teleoperator as one batch."""
    start = time.perf_counter()
    records = [{str(k): v for k, v in record.items()} for record in rows.to_dict("records")]
    params = _model_params(records[0])
    n = params.n_joints
    forward, backward, reference = zip(*(_scenario_inputs(row, n, traces)
                                         for row in records), strict=True)
    scenario = Scenario(params, stack_delays(forward), stack_delays(backward),
                        np.array(reference))
    controller = str(records[0]["controller"])
    if controller == "fixed":
        gains = np.repeat(rows[["kr", "br"]].to_numpy(dtype=float), n, axis=1)
        metrics = _run(Simulator(scenario, task.dt, task.control_period), gains, task)
    else:
        metrics = _run_policy(scenario, task.policies[controller], task)
    out = rows.reset_index(drop=True)
    for i in range(n):
        out[f"G_{i + 1}"] = scenario.reference_gains[:, i]
    out["delay_bound"] = [max(f.bound, b.bound) for f, b in zip(forward, backward, strict=True)]
    out = pd.concat([out, metrics], axis=1)
    out["wall_time"] = (time.perf_counter() - start) / len(rows)
    return out


def _run(sim: Simulator, gains: np.ndarray, task: ChunkTask) -> pd.DataFrame:
    """Simulate ``task.duration`` seconds in one-second blocks, accumulating the metrics."""
    periods = max(1, round(task.duration / task.control_period))
    block = max(1, round(1.0 / task.control_period))
    metrics = RunningMetrics(sim.state)
    for first in range(0, periods, block):
        count = min(block, periods - first)
        metrics.add(sim.advance(np.broadcast_to(gains, (count, *gains.shape))))
    return metrics.frame(Divergence(task.divergence_radius)).assign(unsafe_actions=np.nan)


def _run_policy(scenario: Scenario, policy: GainPolicy, task: ChunkTask) -> pd.DataFrame:
    """Simulate ``task.duration`` seconds, the policy's gains projected every period.

    The loop is the environments' (:class:`~teleopkit.rl.env.TeleopBatch`), on the closed-form
    certificate of the scenario's teleoperator.
    """
    params = scenario.params
    config = FlexTeleopConfig(Setup.from_params(params), default_certificate(params), task.duration,
                              task.control_period, task.dt)
    core = TeleopBatch(config, scenario.batch)
    obs = core.start(scenario)
    metrics = RunningMetrics(core.loop.simulator.state)
    for _ in range(config.max_steps):
        step = core.step(policy(obs))
        metrics.add(step.result)
        obs = step.obs
    frame = metrics.frame(Divergence(task.divergence_radius))
    return frame.assign(unsafe_actions=core.loop.unsafe_by_run.astype(float))


def simulate_chunk(task: ChunkTask,
                   traces: Mapping[str, TraceDelay] | None = None) -> pd.DataFrame:
    """Simulate one chunk of scenarios (the body of a Dask task).

    Scenarios sharing a teleoperator run as one batch of the simulator (on a Dask cluster each
    worker runs numba on one thread: the workers provide the parallelism).

    Parameters
    ----------
    task : ChunkTask
        The chunk.
    traces : mapping of str to TraceDelay, optional
        The campaign's delay traces (:meth:`~teleopkit.robustness.spec.CampaignSpec.traces`),
        needed when a row's delay is ``csv:PATH``.

    Returns
    -------
    pandas.DataFrame
        The chunk's rows with the result columns, sorted by ``scenario``.
    """
    groups = task.rows.groupby([*MODEL_FACTORS, "controller"], sort=False)
    parts = [_simulate_group(task, rows, traces or {}) for _, rows in groups]
    table = pd.concat(parts, ignore_index=True).sort_values("scenario", ignore_index=True)
    table.insert(1, "chunk", np.int64(task.chunk))
    return table


def plan_chunks(scenarios: pd.DataFrame, chunk: int) -> list[np.ndarray]:
    """Cut the scenarios into chunks of at most ``chunk`` rows, grouped by teleoperator.

    Rows are ordered by their model factors (stably), so a chunk holds as few distinct
    teleoperators as possible.

    Parameters
    ----------
    scenarios : pandas.DataFrame
        Output of :meth:`~teleopkit.robustness.spec.CampaignSpec.expand`.
    chunk : int
        Largest number of scenarios per chunk.

    Returns
    -------
    list of ndarray
        The sorted ``scenario`` ids of each chunk; chunk ``k`` is the ``k``-th entry.
    """
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise ValueError(f"chunk must be an integer >= 1, got {chunk!r}")
    ordered = scenarios.sort_values(list(MODEL_FACTORS), kind="stable")["scenario"].to_numpy()
    return [np.sort(ordered[i:i + chunk]) for i in range(0, len(ordered), chunk)]
