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
from teleopkit.delays.profiles import TraceDelay
from teleopkit.delays.spec import check_delay_bound
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
from teleopkit.setup.network import spec_reach
from teleopkit.sim.divergence import Divergence
from teleopkit.sim.metrics import RunningMetrics
from teleopkit.sim.motions import RecordedMotion, SineMotion
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.stability import check_motor_damping, check_step

__all__ = ["METRIC_COLUMNS", "ChunkTask", "check_row_delays", "check_steps", "plan_chunks",
           "simulate_chunk"]

METRIC_COLUMNS = ("rms_track", "iae_track", "max_track", "rms_damp", "iae_damp", "max_damp",
                  "max_position", "growth", "diverged", "unsafe_actions", "wall_time")
"""Result columns after the factor columns, the reference gains ``G_i`` and ``delay_bound``.
``unsafe_actions`` counts a policy's applied actions outside the certified set (NaN for fixed
gains, which no safety layer sees)."""


def _model_params(row: Mapping[str, Any] | pd.Series, base: TeleoperatorParams
                  ) -> TeleoperatorParams:
    """The setup's teleoperator ``base`` with the row's model factors (NaN: the base's own)."""
    n = base.n_joints

    def per_joint(name: str, values: tuple[float, ...]) -> tuple[float, ...]:
        value = float(row[name])
        return values if np.isnan(value) else (value,) * n

    def arm(source: PlanarArm, scale: float) -> PlanarArm:
        inertia = None if source.inertia is None else tuple(scale * i for i in source.inertia)
        return replace(source, masses=tuple(scale * m for m in source.masses), inertia=inertia)

    return replace(
        base,
        local_arm=arm(base.local_arm, float(row["local_mass_scale"])),
        remote_arm=arm(base.remote_arm, float(row["remote_mass_scale"])),
        joints=ElasticJoints(per_joint("joint_stiffness", base.joints.stiffness),
                             per_joint("rotor_inertia", base.joints.rotor_inertia)),
        local_gains=PDGains(per_joint("kl", base.local_gains.stiffness),
                            per_joint("bl", base.local_gains.damping)))


def check_steps(scenarios: pd.DataFrame, dt: float, control_period: float,
                base: TeleoperatorParams | None = None) -> None:
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
    base : TeleoperatorParams, optional
        The setup's teleoperator the factors apply to; the paper's by default.

    Raises
    ------
    ValueError
        One line naming the plant's factors and the largest stable step or gain.
    """
    base = base if base is not None else paper_setup()
    for _, rows in scenarios.groupby(list(MODEL_FACTORS), sort=False, dropna=False):
        row = rows.iloc[0]
        params = _model_params(row, base)
        plant = ", ".join(f"{name}={row[name]:g}" for name in MODEL_FACTORS)
        fixed = rows["br"][rows["controller"] == "fixed"]
        try:
            check_step(params, dt, control_period)
            if len(fixed):
                check_motor_damping(params, dt, fixed.max(), "br", control_period)
        except ValueError as error:
            raise ValueError(f"plant {plant}: {error}") from None


def check_row_delays(scenarios: pd.DataFrame, duration: float, setup: Setup,
                     traces: Mapping[str, TraceDelay]) -> None:
    """Check, before any simulation, that no row's delays reach the run's length.

    Each row's ``delay_bound`` (its drawn delays' bound times ``delay_scale``) must be shorter
    than ``duration``, as :func:`teleopkit.simulate` requires of its run
    (:func:`~teleopkit.delays.spec.check_delay_bound`). Rows whose delay level cannot reach the
    duration pass at once; the others draw their delays from their seeds.

    Parameters
    ----------
    scenarios : DataFrame
        The campaign's rows (:meth:`~teleopkit.robustness.spec.CampaignSpec.expand`).
    duration : float
        Length of each run in seconds.
    setup : Setup
        The setup whose network the level ``setup`` draws.
    traces : mapping of str to TraceDelay
        The campaign's delay traces, keyed by level.

    Raises
    ------
    ValueError
        One line naming the first such row (scenario, delay, delay_scale, seed) and its delay.
    """
    reach = {level: _level_reach(str(level), setup, traces)
             for level in scenarios["delay"].unique()}
    near = scenarios["delay"].map(reach) * scenarios["delay_scale"] >= duration
    for row in scenarios[near].to_dict("records"):
        drawn = _row_scenario({str(k): v for k, v in row.items()}, setup, setup.params, traces)
        try:
            check_delay_bound(max(drawn.forward.bound, drawn.backward.bound), duration,
                              units_hint=row["delay_scale"] == 1)  # drawn: scaled already
        except ValueError as error:
            raise ValueError(f"scenario {row['scenario']} (delay {row['delay']}, delay_scale "
                             f"{row['delay_scale']:g}, seed {row['seed']}): {error}") from None


def _level_reach(level: str, setup: Setup, traces: Mapping[str, TraceDelay]) -> float:
    """The longest delay a ``delay`` level can draw in either direction (before its scale)."""
    if level in traces:
        return float(traces[level].bound)
    specs = ([(spec, 0) for spec in setup.network.forward.profiles]
             + [(spec, 1) for spec in setup.network.backward.profiles]
             if level == "setup" else [(level, 0), (level, 1)])
    return max(spec_reach(spec, direction)[1] for spec, direction in specs)


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
    setup : Setup
        The setup whose plant the model factors change and whose operator motions, starts
        and (for the delay level ``setup``) network the rows draw from their seeds.
    """

    chunk: int
    rows: pd.DataFrame
    duration: float
    dt: float
    control_period: float
    divergence_radius: float
    policies: Mapping[str, GainPolicy] = field(default_factory=dict)
    setup: Setup = field(default_factory=Setup.paper)


def _row_scenario(row: Mapping[str, Any], setup: Setup, params: TeleoperatorParams,
                  traces: Mapping[str, TraceDelay]) -> Scenario:
    """One row's scenario, drawn from its seed as :meth:`Setup.scenarios` draws it.

    The operator motion first, then the delays (the setup's network for the level ``setup``,
    else the row's spec), then the start; a ``reference_gain`` level other than ``random``
    replaces the drawn gains, and ``delay_scale`` scales both delays.
    """
    spec = str(row["delay"])
    delay = None if spec == "setup" else (traces[spec], traces[spec]) if spec in traces else spec
    scenario = replace(setup, params=params).scenarios(int(row["seed"]), 1, delay)
    reference = reference_gains(str(row["reference_gain"]), params.n_joints,
                                scenario.reference_gains[0])
    scale = float(row["delay_scale"])
    return replace(scenario, forward=scale_delay(scenario.forward, scale),
                   backward=scale_delay(scenario.backward, scale),
                   reference_gains=reference[None])


def _stacked(parts: list[Scenario]) -> Scenario:
    """Scenarios of one teleoperator side by side (a shared motion stays shared)."""
    first = parts[0].motion
    same = all(_same_motion(part.motion, first) for part in parts)
    if same:
        motion = first
    elif all(isinstance(part.motion, SineMotion) for part in parts):
        motion = SineMotion(*(np.concatenate([getattr(part.motion, name) for part in parts])
                              for name in ("amplitudes", "frequencies", "phases", "decays")))
    else:  # pragma: no cover - a setup draws sines or one recorded motion
        raise ValueError("rows of one batch draw motions that cannot be stacked")
    return Scenario(parts[0].params, stack_delays([p.forward for p in parts]),
                    stack_delays([p.backward for p in parts]),
                    np.vstack([p.reference_gains for p in parts]), motion,
                    np.concatenate([p.starts for p in parts]))


def _same_motion(motion: Any, other: Any) -> bool:
    """Whether two drawn motions are the same function of time."""
    if isinstance(motion, RecordedMotion) and isinstance(other, RecordedMotion):
        return bool(np.array_equal(motion.times, other.times)
                    and np.array_equal(motion.angles, other.angles))
    if isinstance(motion, SineMotion) and isinstance(other, SineMotion):
        return all(np.array_equal(getattr(motion, name), getattr(other, name))
                   for name in ("amplitudes", "frequencies", "phases", "decays"))
    return False


def _simulate_group(task: ChunkTask, rows: pd.DataFrame,
                    traces: Mapping[str, TraceDelay]) -> pd.DataFrame:
    """Simulate scenarios sharing one teleoperator as one batch."""
    start = time.perf_counter()
    records = [{str(k): v for k, v in record.items()} for record in rows.to_dict("records")]
    params = _model_params(records[0], task.setup.params)
    n = params.n_joints
    parts = [_row_scenario(row, task.setup, params, traces) for row in records]
    scenario = _stacked(parts)
    controller = str(records[0]["controller"])
    if controller == "fixed":
        gains = np.repeat(rows[["kr", "br"]].to_numpy(dtype=float), n, axis=1)
        metrics = _run(Simulator(scenario, task.dt, task.control_period), gains, task)
    else:
        metrics = _run_policy(scenario, task.policies[controller], task)
    out = rows.reset_index(drop=True)
    for i in range(n):
        out[f"G_{i + 1}"] = scenario.reference_gains[:, i]
    out["delay_bound"] = [max(p.forward.bound, p.backward.bound) for p in parts]
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
    groups = task.rows.groupby([*MODEL_FACTORS, "controller"], sort=False, dropna=False)
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
