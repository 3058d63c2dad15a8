"""Held-out evaluation of gain controllers: TD3 policies against fixed and best static gains.

Every controller is run in closed loop through the core of the environments
(:class:`~teleopkit.rl.env.TeleopBatch`), so every applied action goes through the same safety
layer and is counted if it lies outside the certified set (``unsafe_actions``, which must be 0).
The scenarios are drawn from the environment's setup (:class:`~teleopkit.setup.Setup`, the
paper's by default) with the evaluation seed: operator motions, delays and starts that training
never saw (training draws its
scenarios from generators seeded by :class:`~teleopkit.rl.recipes.TrainConfig`, the static-gain
search from :data:`~teleopkit.rl.baselines.BASELINE_SEED`).

Per scenario: RMS and IAE (and maxima) of the tracking error ``theta_r - q_l(t - T_l)`` and the
damping error ``theta_r - q_r`` (Euclidean norm over joints, from ``t = 0``), the paper's cost
(minus the episode return under the environment's reward weights) and its split into the opening
transient (``cost_opening``, the first :data:`OPENING` seconds) and the rest (``cost_rest``), the
mean applied gains and the mean projection distance. :func:`summarise` reduces them per controller
to the mean and standard deviation over scenarios; a controller given as several policies (for
example one per training seed) also gets the standard deviation of the per-policy means
(``seed_std``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from gymnasium.utils import seeding

from teleopkit.certification.gain_classes import parse_gain_variation
from teleopkit.delays.spec import check_trace_ends
from teleopkit.rl.env import BatchStep, FlexTeleopConfig, TeleopBatch
from teleopkit.setup import Setup
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.trajectory import Trajectory

__all__ = [
    "EVAL_SEED",
    "SUMMARY_METRICS",
    "TABLE_METRICS",
    "Controller",
    "Rollout",
    "closed_loop",
    "cost_ratio",
    "episode_costs",
    "evaluate",
    "findings",
    "paired_difference",
    "rollout",
    "save_report",
    "summarise",
    "to_markdown",
]

EVAL_SEED = 7_777
"""Default seed of the held-out evaluation scenarios."""

Controller = Callable[[np.ndarray], np.ndarray]
"""Maps observations ``(B, 7 n)`` to raw gains ``(B, 2 n)`` (the environment projects them);
one with a ``reset()`` method keeps state over an episode (:mod:`teleopkit.rl.controllers`)."""

OPENING = 2.0
"""Length in seconds of the opening transient whose share of the cost is reported apart
(``cost_opening``; ``cost_rest`` is the remainder)."""


@dataclass(frozen=True)
class Rollout:
    """A closed-loop run of ``B`` scenarios over ``P`` control periods.

    Attributes
    ----------
    trajectory : Trajectory
        The simulated run from ``t = 0`` (states, delayed signals, delays, applied gains).
    obs : ndarray, shape (P + 1, B, 7 n)
        Observations (row 0 at ``t = 0``).
    raw : ndarray, shape (P, B, 2 n)
        Gains the controller asked for.
    reward : ndarray, shape (P, B)
        Rewards.
    levels : ndarray, shape (P + 1, B)
        The safety layer's run-time level (budget or tank left; NaN without one) just after
        each sample, its jump paid; the last row at the end (as
        :meth:`~teleopkit.safety.CertifiedLoop.run`).
    unsafe_actions : int
        Applied actions outside the certified set (must be 0).
    certificate : str
        Gain class of the certificate the run was projected onto.
    """

    trajectory: Trajectory
    obs: np.ndarray
    raw: np.ndarray
    reward: np.ndarray
    levels: np.ndarray
    unsafe_actions: int
    certificate: str = "frozen"

    @property
    def t(self) -> np.ndarray:
        """Times, shape ``(P + 1,)``, from 0."""
        return self.trajectory.t

    @property
    def applied(self) -> np.ndarray:
        """Applied (certified) gains of each period, shape ``(P, B, 2 n)``."""
        return self.trajectory.gains[1:]

    def metrics(self) -> pd.DataFrame:
        """Per-scenario errors, cost, mean gains, projection distance and certificate coverage.

        ``gain_changes`` counts the periods whose applied gains differ from the previous
        period's; ``covered`` says whether the certificate's class covers that (constant gains
        are covered by every class, changing gains by every class but ``frozen``).
        """
        table = self.trajectory.metrics()
        table["cost"] = -self.reward.sum(axis=0)
        opening = self.t[1:] <= OPENING + 1e-9
        table["cost_opening"] = -self.reward[opening].sum(axis=0)
        table["cost_rest"] = table["cost"] - table["cost_opening"]
        n = self.applied.shape[-1] // 2
        for i in range(n):
            table[f"mean_Kr_{i + 1}"] = self.applied[:, :, i].mean(axis=0)
            table[f"mean_Br_{i + 1}"] = self.applied[:, :, n + i].mean(axis=0)
        table["projection_distance"] = np.linalg.norm(self.raw - self.applied, axis=-1).mean(0)
        table["unsafe_actions"] = self.unsafe_actions
        changes = np.any(np.diff(self.applied, axis=0) != 0, axis=-1).sum(axis=0)
        table["gain_changes"] = changes
        table["certificate"] = self.certificate
        table["covered"] = (changes == 0) | parse_gain_variation(self.certificate).covers_changes
        return table

    def to_frame(self, scenario: int = 0) -> pd.DataFrame:
        """One scenario as a table (the columns the paper figures need).

        Parameters
        ----------
        scenario : int
            Index of the scenario in the batch.

        Returns
        -------
        pandas.DataFrame
            The columns of :meth:`~teleopkit.sim.trajectory.Trajectory.to_frame` (row 0 holds
            the first period's gains) plus ``Kr_raw_i, Br_raw_i``, the gains asked for.
        """
        frame = self.trajectory.to_frame(scenario)
        raw = np.concatenate([self.raw[:1], self.raw])[:, scenario]
        n = raw.shape[-1] // 2
        for i in range(n):
            frame[f"Kr_raw_{i + 1}"] = raw[:, i]
            frame[f"Br_raw_{i + 1}"] = raw[:, n + i]
        return frame


def rollout(controller: Controller, scenarios: int = 32, seed: int = EVAL_SEED,
            config: FlexTeleopConfig | None = None, delay: str | None = None) -> Rollout:
    """Run a controller on ``scenarios`` held-out scenarios for one episode.

    The scenarios are those :class:`~teleopkit.rl.env.FlexTeleopVectorEnv` draws after
    ``reset(seed=seed)``, and every action passes through the same safety layer.

    Parameters
    ----------
    controller : Controller
        Observations to raw gains (for example a :class:`~teleopkit.rl.policy.GainPolicy`).
    scenarios : int
        Number of scenarios, simulated together.
    seed : int
        Seed of the scenario draws (the same seed gives the same scenarios to every controller).
    config : FlexTeleopConfig, optional
        Environment settings and the setup the scenarios are drawn from.
    delay : str, optional
        Delay profiles of both channels in place of the setup's network
        (:func:`~teleopkit.delays.spec.parse_delay`), for example a shape the controller never
        saw (``"switching:0:1:50ms"``); the operator motions are the same either way.

    Returns
    -------
    Rollout
        The run.
    """
    config = config if config is not None else FlexTeleopConfig()
    rng = seeding.np_random(seed)[0]
    # what TeleopBatch.draw draws, with the delays replaced if asked
    scenario = config.setup.scenarios(rng, scenarios, None if delay == "paper" else delay)
    check_trace_ends((scenario.forward, scenario.backward), config.episode_length)
    return closed_loop(controller, scenario, config)


def closed_loop(controller: Controller, scenario: Scenario,
                config: FlexTeleopConfig | None = None) -> Rollout:
    """Run a controller in closed loop on given scenarios for one episode.

    Parameters
    ----------
    controller : Controller
        Observations to raw gains.
    scenario : Scenario
        The batch of scenarios (plant, delays, operator reference gains).
    config : FlexTeleopConfig, optional
        Environment settings (its ``params`` are replaced by the scenario's).

    Returns
    -------
    Rollout
        The run.

    Raises
    ------
    RuntimeError
        If a run leaves the state bound (a model failure under certified gains).
    """
    core, obs = _started(controller, scenario, config)
    records: dict[str, list[np.ndarray]] = {"obs": [obs], "raw": [], "reward": [], "levels": []}
    parts, applied = [core.loop.simulator.initial_record()], []
    for step in _played(controller, core, obs):
        parts.append(step.result)
        applied.append(step.info["applied_action"])
        level = step.info.get("schedule", np.full(scenario.batch, np.nan))
        for key, value in (("obs", step.obs), ("raw", step.info["raw_action"]),
                           ("reward", step.reward), ("levels", level)):
            records[key].append(value)
    final = core.layer.run_time_state(scenario.batch)
    records["levels"].append(final[:, 0] if final.shape[1] else np.full(scenario.batch, np.nan))
    arrays = {key: np.stack(value) for key, value in records.items()}
    trajectory = Trajectory.join(parts, np.stack(applied))
    return Rollout(trajectory, unsafe_actions=core.unsafe_actions,
                   certificate=core.certificate.gain_variation, **arrays)


def episode_costs(controller: Controller, scenario: Scenario,
                  config: FlexTeleopConfig | None = None) -> tuple[np.ndarray, int]:
    """The episode cost of each scenario under a controller, and nothing else.

    :func:`closed_loop` without its records (a third of its time on large batches): what a
    search that only compares costs needs.

    Parameters
    ----------
    controller : Controller
        Observations to raw gains.
    scenario : Scenario
        The batch of scenarios.
    config : FlexTeleopConfig, optional
        Environment settings (its ``params`` are replaced by the scenario's).

    Returns
    -------
    costs : ndarray, shape (B,)
        Minus the summed rewards: the same as ``-closed_loop(...).reward.sum(axis=0)``.
    unsafe_actions : int
        Applied gains outside the certified set (0 expected).

    Raises
    ------
    RuntimeError
        If a run leaves the state bound (a model failure under certified gains).
    """
    core, obs = _started(controller, scenario, config)
    costs = np.zeros(scenario.batch)
    for step in _played(controller, core, obs):
        costs -= step.reward
    return costs, core.unsafe_actions


def _started(controller: Controller, scenario: Scenario,
             config: FlexTeleopConfig | None) -> tuple[TeleopBatch, np.ndarray]:
    """The batch of the scenarios, started, the controller reset; the first observation."""
    config = config if config is not None else FlexTeleopConfig()
    if scenario.plants != config.setup.plants:
        setup = Setup.from_params(scenario.params, config.setup.network)
        config = replace(config, setup=replace(setup, other_plants=scenario.other_plants))
    core = TeleopBatch(config, scenario.batch)
    reset = getattr(controller, "reset", None)
    if callable(reset):
        reset()
    return core, core.start(scenario)


def _played(controller: Controller, core: TeleopBatch, obs: np.ndarray) -> Iterator[BatchStep]:
    """Every step of one episode of ``core`` under ``controller``, from ``obs``."""
    for _ in range(core.config.max_steps):
        step = core.step(np.asarray(controller(obs), dtype=float))
        if step.terminated.any():
            raise RuntimeError("a certified controller left the state bound (a model failure)")
        obs = step.obs
        yield step


def evaluate(controllers: Mapping[str, Controller | Sequence[Controller]], scenarios: int = 32,
             seed: int = EVAL_SEED, config: FlexTeleopConfig | None = None,
             configs: Mapping[str, FlexTeleopConfig] | None = None,
             delay: str | None = None) -> pd.DataFrame:
    """Per-scenario metrics of every controller on the same held-out scenarios.

    Parameters
    ----------
    controllers : mapping of str to Controller or sequence of Controller
        Named controllers; a sequence is several policies of one kind (e.g. training seeds).
    scenarios : int
        Scenarios per controller.
    seed : int
        Evaluation seed.
    config : FlexTeleopConfig, optional
        Environment settings.
    configs : mapping of str to FlexTeleopConfig, optional
        Settings of particular controllers (for example another certificate), by name;
        ``config`` for the others.
    delay : str, optional
        Delay profiles in place of the setup's network (:func:`rollout`).

    Returns
    -------
    pandas.DataFrame
        One row per (controller, policy, scenario) with the columns of :meth:`Rollout.metrics`.
    """
    frames = []
    for name, entry in controllers.items():
        policies = list(entry) if isinstance(entry, Sequence) else [entry]
        for index, policy in enumerate(policies):
            settings = (configs or {}).get(name, config)
            table = rollout(policy, scenarios, seed, settings, delay).metrics().reset_index()
            table.insert(0, "policy", index)
            table.insert(0, "controller", name)
            frames.append(table)
    return pd.concat(frames, ignore_index=True)


SUMMARY_METRICS = ("cost", "cost_opening", "cost_rest", "rms_track", "iae_track", "rms_damp",
                   "iae_damp")
"""Metrics reported by :func:`summarise`."""

TABLE_METRICS = ("cost", "cost_opening", "cost_rest", "rms_track", "rms_damp")
"""Metrics of the markdown tables (:func:`to_markdown`, ``summary.md``)."""


def summarise(per_scenario: pd.DataFrame,
              metrics: Sequence[str] = SUMMARY_METRICS) -> pd.DataFrame:
    """Mean and standard deviations per controller.

    Parameters
    ----------
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate`.
    metrics : sequence of str
        Columns to summarise.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``controller`` (in input order): ``certificate`` (the gain class it ran
        under), ``covered`` (whether that class covers what it did with the gains, in every
        scenario), then per metric its mean ``<metric>``, ``<metric>_std`` (over all scenarios
        and policies) and ``<metric>_seed_std`` (over the per-policy means; NaN for one policy),
        plus ``policies``, ``scenarios`` and the total ``unsafe_actions``.
    """
    order = list(dict.fromkeys(per_scenario["controller"]))
    grouped = per_scenario.groupby("controller", sort=False)
    per_policy = per_scenario.groupby(["controller", "policy"], sort=False)[list(metrics)].mean()
    columns: dict[str, pd.Series] = {"certificate": grouped["certificate"].first(),
                                     "covered": grouped["covered"].all()}
    for metric in metrics:
        columns[metric] = grouped[metric].mean()
        columns[f"{metric}_std"] = grouped[metric].std(ddof=1)
        columns[f"{metric}_seed_std"] = per_policy[metric].groupby(level=0, sort=False).std(ddof=1)
    columns["policies"] = grouped["policy"].nunique()
    columns["scenarios"] = grouped["scenario"].nunique()
    unsafe = per_scenario.drop_duplicates(["controller", "policy"])
    columns["unsafe_actions"] = unsafe.groupby("controller", sort=False)["unsafe_actions"].sum()
    return pd.DataFrame(columns).loc[order]


def to_markdown(summary: pd.DataFrame, metrics: Sequence[str] = TABLE_METRICS,
                baseline: str | None = None) -> str:
    """A markdown table of ``mean ± std`` per controller, with its certificate and coverage.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    metrics : sequence of str
        Metrics to show.
    baseline : str, optional
        Controller whose mean cost the others are compared with (a ``cost vs <baseline>``
        column in percent).

    Returns
    -------
    str
        The table.
    """
    header = ["controller", "certificate", "covered", *metrics]
    if baseline is not None:
        header.append(f"cost vs {baseline}")
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for name, row in summary.iterrows():
        cells = [str(name), str(row["certificate"]), "yes" if row["covered"] else "no"]
        for metric in metrics:
            cell = f"{row[metric]:.4g} ± {row[f'{metric}_std']:.2g}"
            if row["policies"] > 1:
                cell += f" (seeds ± {row[f'{metric}_seed_std']:.2g})"
            cells.append(cell)
        if baseline is not None:
            change = row["cost"] / summary.loc[baseline, "cost"] - 1
            cells.append(f"{100 * change:+.1f} %")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def paired_difference(per_scenario: pd.DataFrame, first: str,
                      second: str) -> tuple[float, float, float]:
    """Cost of ``first`` against ``second``: relative change, paired mean difference, its error.

    Paired over the scenarios both ran (per-policy costs averaged per scenario); the error is
    the standard error of the mean difference (NaN for one scenario).

    Parameters
    ----------
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate` with both rows.
    first, second : str
        The rows compared.

    Returns
    -------
    tuple of float
        The change of the mean cost (a fraction of ``second``'s), the mean per-scenario
        difference and its standard error (cost units).
    """
    cost = per_scenario.groupby(["controller", "scenario"], sort=False)["cost"].mean()
    difference = (cost.loc[first] - cost.loc[second]).dropna()
    error = difference.std(ddof=1) / np.sqrt(len(difference))
    relative = cost.loc[first].mean() / cost.loc[second].mean() - 1
    return float(relative), float(difference.mean()), float(error)


def cost_ratio(per_scenario: pd.DataFrame, first: str, second: str) -> tuple[float, float]:
    """Mean over the scenarios of ``cost(first) / cost(second) - 1``, and its standard error.

    Every scenario weighs the same, however costly: the mean cost is led by the dearest runs
    (a start far from the operator can cost ten times the paper's), this ratio by the typical.

    Parameters
    ----------
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate` with both rows (per-policy costs averaged per scenario).
    first, second : str
        The rows compared.

    Returns
    -------
    tuple of float
        The mean relative change and its standard error (fractions; NaN error for one
        scenario).
    """
    cost = per_scenario.groupby(["controller", "scenario"], sort=False)["cost"].mean()
    ratio = (cost.loc[first] / cost.loc[second]).dropna()
    return float(ratio.mean() - 1), float(ratio.std(ddof=1) / np.sqrt(len(ratio)))


def _against(per_scenario: pd.DataFrame, tuner: str, other: str) -> str:
    """The tuner against another row: mean cost, paired difference, mean ratio, verdict."""
    relative, mean, error = paired_difference(per_scenario, tuner, other)
    ratio, ratio_error = cost_ratio(per_scenario, tuner, other)
    verdict = ("the same cost to rounding" if abs(relative) < 1e-9 else
               "no measurable difference in mean cost on these scenarios" if abs(mean) <= 2 * error
               else "cheaper" if mean < 0 else "dearer")
    return (f"{100 * relative:+.1f} % cost (paired over the scenarios: {mean:+.4g} "
            f"± {error:.2g} per scenario, mean ± standard error; scenario by scenario "
            f"{100 * ratio:+.1f} ± {100 * ratio_error:.1f} % on average), {verdict}")


def findings(summary: pd.DataFrame, per_scenario: pd.DataFrame, tuner: str,
             baseline: str, schedule: str | None = None) -> str:
    """What the table says of the tuner, in words: against the strongest covered alternative.

    The rows covered by their certificate are ranked by mean cost. The tuner is compared with
    the cheapest other covered row, paired scenario by scenario: a mean difference within twice
    its standard error is reported as no measurable difference; the mean over the scenarios of
    the ratio of costs follows (every scenario weighed the same). Then the same against the
    tuner's own open-loop schedule, when it has a row: whether its feedback pays over its mean
    gains replayed blind. Cheaper rows that their certificate does not cover are named as such.

    Parameters
    ----------
    summary : pandas.DataFrame
        :func:`summarise` of ``per_scenario``.
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate`, with the rows ``tuner`` and ``baseline``.
    tuner : str
        The tuner's row.
    baseline : str
        The row costs are compared with in percent.
    schedule : str, optional
        The row of the tuner's open-loop mean schedule, if any.

    Returns
    -------
    str
        A markdown paragraph.
    """
    covered = summary[summary["covered"]].sort_values("cost")
    cost = summary["cost"]
    change = cost / cost[baseline] - 1
    best = str(covered.index[0]) if len(covered) else ""
    lines = [f"Of the rows covered by their certificate, `{best}` costs least "
             f"({100 * change[best]:+.1f} % against `{baseline}`)." if best else
             "No row is covered by its certificate."]
    rivals = [name for name in covered.index if name != tuner]
    if summary.loc[tuner, "covered"] and rivals:
        rival = str(rivals[0])
        lines.append(f"`{tuner}` against the strongest other covered row, `{rival}`: "
                     f"{_against(per_scenario, tuner, rival)}.")
        if schedule is not None and schedule != rival and schedule in summary.index:
            lines.append(f"Against its own open-loop schedule, `{schedule}` (its feedback "
                         f"against its mean gains replayed blind): "
                         f"{_against(per_scenario, tuner, schedule)}.")
    elif not summary.loc[tuner, "covered"]:
        lines.append(f"`{tuner}` is not covered by its certificate.")
    cheaper = [str(name) for name in summary.index
               if not summary.loc[name, "covered"] and summary.loc[name, "cost"]
               < summary.loc[tuner, "cost"]]
    if cheaper:
        lines.append("Cheaper but not covered by their certificate: "
                     + ", ".join(f"`{name}` ({100 * change[name]:+.1f} %)" for name in cheaper)
                     + ".")
    return " ".join(lines) + "\n"


def save_report(per_scenario: pd.DataFrame, out_dir: str | Path,
                baseline: str | None = None, preamble: str = "",
                tuner: str | None = None, schedule: str | None = None) -> pd.DataFrame:
    """Write ``per_scenario.csv``, ``summary.csv`` and ``summary.md`` to ``out_dir``.

    Parameters
    ----------
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate`.
    out_dir : str or Path
        Directory (created if needed).
    baseline : str, optional
        Controller the markdown table compares costs with.
    preamble : str
        Markdown that ``summary.md`` opens with (what was compared, what the words mean).
    tuner : str, optional
        The tuner's row: ``summary.md`` then ends with :func:`findings` (needs ``baseline``).
    schedule : str, optional
        The row of the tuner's open-loop mean schedule, for :func:`findings`.

    Returns
    -------
    pandas.DataFrame
        The summary.
    """
    directory = Path(out_dir)
    directory.mkdir(parents=True, exist_ok=True)
    summary = summarise(per_scenario)
    per_scenario.to_csv(directory / "per_scenario.csv", index=False)
    summary.to_csv(directory / "summary.csv")
    table = to_markdown(summary, baseline=baseline)
    if tuner is not None and baseline is not None:
        table += "\n" + findings(summary, per_scenario, tuner, baseline, schedule)
    (directory / "summary.md").write_text(f"{preamble}\n{table}" if preamble else table)
    return summary
