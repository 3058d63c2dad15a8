"""Held-out evaluation of gain controllers: TD3 policies against fixed and best static gains.

Every controller is run in closed loop through the same batched
:class:`~teleopkit.env.FlexTeleopVectorEnv`, so every applied action goes through the same safety
layer and is counted if it lies outside the certified set (``unsafe_actions``, which must be 0).
The scenarios are drawn by :func:`~teleopkit.scenarios.paper_scenarios` from the evaluation seed:
operator reference gains and delay scales that training never saw (training draws its scenarios
from generators seeded by :class:`~teleopkit.training.TrainConfig`, the static-gain search from
:data:`~teleopkit.baselines.BASELINE_SEED`).

Per scenario: RMS and IAE (and maxima) of the tracking error ``theta_r - q_l(t - T_l)`` and the
damping error ``theta_r - q_r`` (Euclidean norm over joints, from ``t = 0``), the paper's cost
(minus the episode return under the environment's reward weights), the mean applied gains and the
mean projection distance. :func:`summarise` reduces them per controller to the mean and standard
deviation over scenarios; a controller given as several policies (for example one per training
seed) also gets the standard deviation of the per-policy means (``seed_std``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from teleopkit.env import FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.metrics import error_metrics

__all__ = [
    "EVAL_SEED",
    "SUMMARY_METRICS",
    "ConstantGains",
    "Controller",
    "Rollout",
    "evaluate",
    "rollout",
    "save_report",
    "summarise",
    "to_markdown",
]

EVAL_SEED = 7_777
"""Default seed of the held-out evaluation scenarios."""

Controller = Callable[[np.ndarray], np.ndarray]
"""Maps observations ``(B, 7 n)`` to raw gains ``(B, 2 n)`` (the environment projects them)."""


@dataclass(frozen=True)
class ConstantGains:
    """A controller that always asks for the same gains.

    Parameters
    ----------
    gains : ndarray, shape (2 n,)
        ``[K_r..., B_r...]``.
    """

    gains: np.ndarray

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The gains, once per observation row."""
        return np.tile(np.asarray(self.gains, dtype=float), (len(obs), 1))


@dataclass(frozen=True)
class Rollout:
    """A closed-loop run of ``B`` scenarios over ``P`` control periods.

    Attributes
    ----------
    t : ndarray, shape (P + 1,)
        Times, from 0.
    obs : ndarray, shape (P + 1, B, 7 n)
        Observations (row 0 at ``t = 0``).
    applied : ndarray, shape (P, B, 2 n)
        Applied gains of each period.
    raw : ndarray, shape (P, B, 2 n)
        Gains the controller asked for.
    delays : ndarray, shape (P, B, 2)
        ``T_l, T_r`` at the end of each period.
    reward : ndarray, shape (P, B)
        Rewards.
    unsafe_actions : int
        Applied actions outside the certified set (must be 0).
    """

    t: np.ndarray
    obs: np.ndarray
    applied: np.ndarray
    raw: np.ndarray
    delays: np.ndarray
    reward: np.ndarray
    unsafe_actions: int

    def _block(self, index: int) -> np.ndarray:
        n = self.obs.shape[-1] // 7
        return self.obs[..., index * n:(index + 1) * n]

    @property
    def e_track(self) -> np.ndarray:
        """Tracking error, shape ``(P + 1, B, n)``."""
        return self._block(3)

    @property
    def e_damp(self) -> np.ndarray:
        """Damping error, shape ``(P + 1, B, n)``."""
        return self._block(5)

    def metrics(self) -> pd.DataFrame:
        """Per-scenario errors, cost, mean gains and projection distance."""
        table = error_metrics(self.t, {"track": self.e_track, "damp": self.e_damp})
        table["cost"] = -self.reward.sum(axis=0)
        n = self.applied.shape[-1] // 2
        for i in range(n):
            table[f"mean_Kr_{i + 1}"] = self.applied[:, :, i].mean(axis=0)
            table[f"mean_Br_{i + 1}"] = self.applied[:, :, n + i].mean(axis=0)
        table["projection_distance"] = np.linalg.norm(self.raw - self.applied, axis=-1).mean(0)
        table["unsafe_actions"] = self.unsafe_actions
        return table

    def to_frame(self, scenario: int = 0) -> pd.DataFrame:
        """One scenario as a table (the columns the paper figures need).

        Columns ``t, theta_i, dtheta_i, ql_delayed_i, e_track_i, e_damp_i, Tl, Tr, Kr_i, Br_i``;
        the delays are NaN at ``t = 0`` and row 0 holds the first period's gains.

        Parameters
        ----------
        scenario : int
            Index of the scenario in the batch.

        Returns
        -------
        pandas.DataFrame
            One row per control period plus the initial row.
        """
        n = self.obs.shape[-1] // 7
        columns: dict[str, np.ndarray] = {"t": self.t}
        gains = np.concatenate([self.applied[:1], self.applied])[:, scenario]
        for name, block in (("theta", 0), ("dtheta", 1), ("ql_delayed", 2), ("e_track", 3),
                            ("e_damp", 5)):
            for i in range(n):
                columns[f"{name}_{i + 1}"] = self._block(block)[:, scenario, i]
        for k, name in enumerate(("Tl", "Tr")):
            columns[name] = np.concatenate([[np.nan], self.delays[:, scenario, k]])
        for i in range(n):
            columns[f"Kr_{i + 1}"] = gains[:, i]
            columns[f"Br_{i + 1}"] = gains[:, n + i]
        return pd.DataFrame(columns)


def rollout(controller: Controller, scenarios: int = 32, seed: int = EVAL_SEED,
            config: FlexTeleopConfig | None = None) -> Rollout:
    """Run a controller on ``scenarios`` held-out scenarios for one episode.

    Parameters
    ----------
    controller : Controller
        Observations to raw gains (for example a :class:`~teleopkit.agent.GainPolicy`).
    scenarios : int
        Number of scenarios, simulated together.
    seed : int
        Seed of the scenario draws (the same seed gives the same scenarios to every controller).
    config : FlexTeleopConfig, optional
        Environment settings.

    Returns
    -------
    Rollout
        The run.
    """
    env = FlexTeleopVectorEnv(scenarios, config)
    obs, _ = env.reset(seed=seed)
    steps = env.config.max_steps
    records: dict[str, list[np.ndarray]] = {"obs": [obs], "applied": [], "raw": [],
                                            "delays": [], "reward": []}
    for _ in range(steps):
        raw = np.asarray(controller(obs), dtype=float)
        obs, reward, terminated, _, info = env.step(raw)
        for key, value in (("obs", obs), ("applied", info["applied_action"]), ("raw", raw),
                           ("delays", info["delays"]), ("reward", reward)):
            records[key].append(value)
        if terminated.any():
            raise RuntimeError("a certified controller left the state bound (a model failure)")
    t = np.arange(steps + 1) * env.config.control_period
    arrays = {key: np.stack(value) for key, value in records.items()}
    return Rollout(t=t, unsafe_actions=env.unsafe_actions, **arrays)


def evaluate(controllers: Mapping[str, Controller | Sequence[Controller]], scenarios: int = 32,
             seed: int = EVAL_SEED, config: FlexTeleopConfig | None = None) -> pd.DataFrame:
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

    Returns
    -------
    pandas.DataFrame
        One row per (controller, policy, scenario) with the columns of :meth:`Rollout.metrics`.
    """
    frames = []
    for name, entry in controllers.items():
        policies = list(entry) if isinstance(entry, Sequence) else [entry]
        for index, policy in enumerate(policies):
            table = rollout(policy, scenarios, seed, config).metrics().reset_index()
            table.insert(0, "policy", index)
            table.insert(0, "controller", name)
            frames.append(table)
    return pd.concat(frames, ignore_index=True)


SUMMARY_METRICS = ("cost", "rms_track", "iae_track", "rms_damp", "iae_damp")
"""Metrics reported by :func:`summarise`."""


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
        Indexed by controller (in input order): ``<metric>_mean``, ``<metric>_std`` (over all
        scenarios and policies), ``<metric>_seed_std`` (over the per-policy means; NaN for one
        policy), plus ``policies``, ``scenarios`` and the total ``unsafe_actions``.
    """
    order = list(dict.fromkeys(per_scenario["controller"]))
    grouped = per_scenario.groupby("controller", sort=False)
    per_policy = per_scenario.groupby(["controller", "policy"], sort=False)[list(metrics)].mean()
    columns: dict[str, pd.Series] = {}
    for metric in metrics:
        columns[f"{metric}_mean"] = grouped[metric].mean()
        columns[f"{metric}_std"] = grouped[metric].std(ddof=1)
        columns[f"{metric}_seed_std"] = per_policy[metric].groupby(level=0, sort=False).std(ddof=1)
    columns["policies"] = grouped["policy"].nunique()
    columns["scenarios"] = grouped["scenario"].nunique()
    unsafe = per_scenario.drop_duplicates(["controller", "policy"])
    columns["unsafe_actions"] = unsafe.groupby("controller", sort=False)["unsafe_actions"].sum()
    return pd.DataFrame(columns).loc[order]


def to_markdown(summary: pd.DataFrame, metrics: Sequence[str] = SUMMARY_METRICS,
                reference: str | None = None) -> str:
    """A markdown table of ``mean ± std`` per controller (no extra dependency).

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    metrics : sequence of str
        Metrics to show.
    reference : str, optional
        Controller whose mean cost the others are compared with (a ``cost vs <reference>``
        column in percent).

    Returns
    -------
    str
        The table.
    """
    header = ["controller", *metrics]
    if reference is not None:
        header.append(f"cost vs {reference}")
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for name, row in summary.iterrows():
        cells = [str(name)]
        for metric in metrics:
            cell = f"{row[f'{metric}_mean']:.4g} ± {row[f'{metric}_std']:.2g}"
            if row["policies"] > 1:
                cell += f" (seeds ± {row[f'{metric}_seed_std']:.2g})"
            cells.append(cell)
        if reference is not None:
            change = row["cost_mean"] / summary.loc[reference, "cost_mean"] - 1
            cells.append(f"{100 * change:+.1f} %")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def save_report(per_scenario: pd.DataFrame, out_dir: str | Path,
                reference: str | None = None) -> pd.DataFrame:
    """Write ``per_scenario.csv``, ``summary.csv`` and ``summary.md`` to ``out_dir``.

    Parameters
    ----------
    per_scenario : pandas.DataFrame
        Output of :func:`evaluate`.
    out_dir : str or Path
        Directory (created if needed).
    reference : str, optional
        Controller the markdown table compares costs with.

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
    (directory / "summary.md").write_text(to_markdown(summary, reference=reference))
    return summary
