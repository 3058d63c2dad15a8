"""``teleopkit train``, ``evaluate`` and ``reproduce``: TD3 gain tuners and their comparison."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from teleopkit.cli.options import (
    certificate_option,
    check_output_dir,
    read_certificate,
    single_thread,
)

if TYPE_CHECKING:
    import pandas as pd

    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.evaluation import Controller
    from teleopkit.rl.policy import GainPolicy

__all__ = ["evaluate_command", "reproduce_command", "train_command"]


def env_config(certificate: Path | None, duration: float) -> FlexTeleopConfig:
    """Environment settings with the certificate read (and re-checked) from a file, if given.

    Parameters
    ----------
    certificate : Path or None
        Certificate file.
    duration : float
        Episode length in seconds.

    Returns
    -------
    FlexTeleopConfig
        The settings; the environments refuse a certificate for another plant or smaller
        delay bounds.
    """
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.sim.scenarios import PAPER_DELAY_BOUND, PAPER_DELAY_FLOOR

    config = FlexTeleopConfig(episode_length=duration)
    if certificate is None:
        return config
    loaded = read_certificate(certificate)
    loaded.check(config.params, PAPER_DELAY_BOUND, PAPER_DELAY_BOUND,
                 (PAPER_DELAY_FLOOR, PAPER_DELAY_FLOOR))  # before any work
    return FlexTeleopConfig(certificate=loaded, episode_length=duration)


@click.command("train")
@click.option("--steps", type=click.IntRange(min=1), default=1_600_000, show_default=True,
              help="Transitions to collect over all environments (rounded up to whole "
                   "episodes of every environment).")
@click.option("--envs", type=click.IntRange(min=1), default=16, show_default=True,
              help="Scenarios simulated together.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Master seed of the run.")
@click.option("--out", type=click.Path(path_type=Path), default="runs/train", show_default=True,
              help="Directory for checkpoint.pt, train_log.csv, policy.npz, best_policy.npz "
                   "and config.json.")
@click.option("--resume", is_flag=True, help="Continue the checkpoint in --out.")
@certificate_option
def train_command(steps: int, envs: int, seed: int, out: Path, resume: bool,
                  certificate: Path | None) -> None:
    """Train a TD3 gain tuner (checkpointed every episode; --resume continues exactly).

    The other settings are the defaults of teleopkit.rl.training.TrainConfig: 40 s episodes, the
    paper's TD3 with learning rates 1e-3 and discount 0.95, best policy kept by
    validation cost.
    """
    from teleopkit.rl.training import CHECKPOINT, TrainConfig, train

    check_output_dir(out, "--out")
    if resume and not (out / CHECKPOINT).is_file():
        raise click.BadParameter(f"no checkpoint in {out} ({CHECKPOINT}); leave --resume out "
                                 "to start a run there", param_hint="'--resume'")
    config = env_config(certificate, 40.0)
    single_thread()
    recipe = TrainConfig(total_steps=steps, num_envs=envs, seed=seed,
                         learning_starts=max(envs, min(TrainConfig.learning_starts, steps)))
    result = train(recipe, out, resume=resume, env_config=config)
    row = result.log.iloc[-1]
    click.echo(f"trained {int(row['step'])} steps; best validation cost "
               f"{result.log['validation_cost'].min():.5g}; policies in {out}")


def best_static(policies: Sequence[GainPolicy], config: FlexTeleopConfig) -> np.ndarray:
    """Best static gains stored with the first policy for its certificate, or found now.

    Parameters
    ----------
    policies : sequence of GainPolicy
        The policies compared (their metadata may hold the gains).
    config : FlexTeleopConfig
        Settings whose certificate's set the gains must lie in.

    Returns
    -------
    ndarray, shape (2 n,)
        The gains.
    """
    from teleopkit.rl.baselines import best_static_gains

    stored = policies[0].metadata.get("best_static_gains")
    if stored is not None and config.certificate is None:
        return np.asarray(stored, dtype=float)
    click.echo("searching the best static certified gains (about a minute) ...", err=True)
    return best_static_gains(config=config).gains


def compare(policies: Sequence[GainPolicy], scenarios: int, seed: int, config: FlexTeleopConfig,
            out: Path, others: Mapping[str, tuple[Controller, FlexTeleopConfig]] | None = None
            ) -> pd.DataFrame:
    """Evaluate TD3, fixed and best static gains; write the report; return the summary.

    Parameters
    ----------
    policies : sequence of GainPolicy
        One or more trained policies (several training seeds of one recipe).
    scenarios : int
        Held-out scenarios.
    seed : int
        Their seed.
    config : FlexTeleopConfig
        Settings (certificate, episode length).
    out : Path
        Directory of the report.
    others : mapping, optional
        More controllers by name, each with its own settings (another certificate).

    Returns
    -------
    pandas.DataFrame
        The summary table.
    """
    from teleopkit.rl.baselines import fixed_gains
    from teleopkit.rl.evaluation import ConstantGains, evaluate, save_report, to_markdown

    controllers: dict[str, Controller | list[Controller]] = {
        "TD3": list(policies), "fixed": ConstantGains(fixed_gains()),
        "best static": ConstantGains(best_static(policies, config))}
    others = others or {}
    controllers.update({name: controller for name, (controller, _) in others.items()})
    per_scenario = evaluate(controllers, scenarios, seed, config,
                            {name: settings for name, (_, settings) in others.items()})
    summary = save_report(per_scenario, out, baseline="best static")
    click.echo(to_markdown(summary, baseline="best static"), nl=False)
    return summary


@click.command("evaluate")
@click.option("--policy", "policy_files", required=True, multiple=True,
              type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Policy file (policy.npz); repeat for several training seeds.")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios.")
@click.option("--seed", type=click.IntRange(min=0), default=7_777, show_default=True,
              help="Seed of the held-out scenarios (teleopkit.rl.evaluation.EVAL_SEED).")
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=40.0,
              show_default=True, help="Episode length [s].")
@click.option("--out", type=click.Path(path_type=Path), default="runs/evaluate",
              show_default=True, help="Directory for per_scenario.csv, summary.csv and summary.md.")
@certificate_option
def evaluate_command(policy_files: tuple[Path, ...], scenarios: int, seed: int,
                     duration: float, out: Path, certificate: Path | None) -> int:
    """Compare TD3 policies with fixed and best static certified gains on held-out scenarios."""
    from teleopkit.rl.policy import GainPolicy

    check_output_dir(out, "--out")
    config = env_config(certificate, duration)
    policies = []
    for path in policy_files:
        try:
            policies.append(GainPolicy.load(path))
        except ValueError as error:
            raise click.BadParameter(str(error), param_hint="'--policy'") from None
    single_thread()
    summary = compare(policies, scenarios, seed, config, out)
    unsafe = int(summary["unsafe_actions"].sum())
    click.echo(f"report in {out}; unsafe actions: {unsafe}")
    return 0 if unsafe == 0 else 1


@click.command("reproduce")
@click.option("--out", type=click.Path(path_type=Path), default="runs/reproduce",
              show_default=True, help="Directory for the figures (PNG) and the comparison table.")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios of the comparison table.")
def reproduce_command(out: Path, scenarios: int) -> int:
    """Paper figures and comparison table from the shipped pretrained policies (no training).

    The table has the paper's tuner (trained under the frozen-gain certificate, which does not
    cover its schedules: ``covered`` is no) and the tuner trained under a scheduled class with
    the best static gains of that class (covered).
    """
    from teleopkit.certification.certifier import default_certificate
    from teleopkit.plots import save_paper_figures
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.evaluation import EVAL_SEED, ConstantGains, rollout
    from teleopkit.rl.policy import PRETRAINED_SCHEDULED, GainPolicy

    check_output_dir(out, "--out")
    single_thread()
    policy = GainPolicy.pretrained()
    config = env_config(None, 40.0)
    covered = GainPolicy.pretrained(PRETRAINED_SCHEDULED)
    variation = covered.metadata["gain_variation"]
    scheduled = FlexTeleopConfig(certificate=default_certificate(variation=variation))
    others = {f"TD3 ({variation})": (covered, scheduled),
              f"best static ({variation})": (
                  ConstantGains(np.asarray(covered.metadata["best_static_gains"])), scheduled)}
    summary = compare([policy], scenarios, EVAL_SEED, config, out, others)
    runs = {"TD3": rollout(policy, 1, EVAL_SEED).to_frame(),
            "best static": rollout(ConstantGains(best_static([policy], config)), 1,
                                   EVAL_SEED).to_frame()}
    paths = save_paper_figures(runs, out)
    unsafe = int(summary["unsafe_actions"].sum())
    click.echo(f"wrote {len(paths)} figures and the table to {out}; unsafe actions: {unsafe}")
    return 0 if unsafe == 0 else 1
