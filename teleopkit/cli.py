"""The ``teleopkit`` command line.

Exit codes: 0 success (or certified), 1 ran but the answer is negative (not certified), 2 bad input
with a one-line message on standard error and no traceback.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from teleopkit.sim.timing import DEFAULT_DT

if TYPE_CHECKING:  # the commands import lazily: ``teleopkit --help`` must stay fast
    import pandas as pd

    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.evaluation import Controller
    from teleopkit.rl.policy import GainPolicy

__all__ = ["cli", "main"]


def _gain_vector(value: str, name: str, n_joints: int = 2) -> list[float]:
    """Parse ``K`` or ``K1,K2`` into one non-negative number per joint."""
    try:
        numbers = [float(x) for x in value.split(",")]
    except ValueError:
        message = f"{name} must be a number or a comma list, got {value!r}"
        raise click.BadParameter(message) from None
    if len(numbers) == 1:
        numbers *= n_joints
    if len(numbers) != n_joints:
        raise click.BadParameter(f"{name} needs 1 or {n_joints} values, got {len(numbers)}")
    if not all(np.isfinite(numbers)) or min(numbers) < 0:
        raise click.BadParameter(f"{name} must be finite and non-negative, got {value!r}")
    return numbers


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="teleopkit")
def cli() -> None:
    """Delayed bilateral teleoperation: simulate, certify, train and evaluate gain tuners."""


@cli.command()
@click.option("--kr", required=True, help="Remote proportional gain K_r: one value or K1,K2.")
@click.option("--br", required=True, help="Remote damping gain B_r: one value or B1,B2.")
@click.option("--duration", type=float, default=40.0, show_default=True, help="Seconds.")
@click.option("--delay", default="paper", show_default=True,
              help="paper | constant:T | sine:MEAN:AMP:FREQ | switching:LOW:HIGH:DWELL | csv:PATH")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the operator reference and the delay scales.")
@click.option("--dt", type=float, default=DEFAULT_DT, show_default=True,
              help="Integration step [s]; 1.25 ms is accurate to 1e-5 rad.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="CSV file for the trajectory.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="PNG file for the paper-style figure.")
def simulate(kr: str, br: str, duration: float, delay: str, seed: int, dt: float, out: Path,
             plot: Path | None) -> None:
    """Simulate the paper's teleoperator with constant remote gains and write the run as CSV."""
    from teleopkit.files import write_csv
    from teleopkit.sim.simulator import simulate_trajectory

    gains = np.array(_gain_vector(kr, "--kr") + _gain_vector(br, "--br"))
    trajectory = simulate_trajectory(gains, duration=duration, delay=delay, seed=seed, dt=dt)
    try:
        write_csv(out, trajectory.columns())
    except OSError as error:
        raise click.FileError(str(out), hint=error.strerror) from None
    if plot is not None:
        from teleopkit.plots import save_run_figure

        save_run_figure(trajectory.to_frame(), plot,
                        title=f"K_r = {kr}, B_r = {br}, delay {delay}")
    e = trajectory.e_track[:, 0]
    rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    click.echo(f"wrote {len(trajectory.t)} rows to {out}; RMS tracking error {rms:.4g} rad")


@cli.command()
@click.option("--kr", "kr_range", required=True, help="Range of K_r, MIN:MAX (every joint).")
@click.option("--br", "br_range", required=True, help="Range of B_r, MIN:MAX (every joint).")
@click.option("--kl", type=float, default=25.0, show_default=True, help="Local gain K_l.")
@click.option("--bl", type=float, default=10.0, show_default=True, help="Local damping B_l.")
@click.option("--tl-max", type=float, default=1.0, show_default=True,
              help="Forward delay bound T_l* [s].")
@click.option("--tr-max", type=float, default=1.0, show_default=True,
              help="Backward delay bound T_r* [s].")
@click.option("--method", type=click.Choice(["nuno", "lmi", "all"]), default="nuno",
              show_default=True,
              help="nuno: closed form (instant); lmi: LK/LMI on the linearisation (seconds per "
                   "joint box, minutes for two joints); all: both, the best answer first.")
@click.option("--gain-variation", "variation", default="frozen", show_default=True,
              help="frozen | switching | rate:R | scheduled:L | tank[:T0] (R in gain units per "
                   "second, L a log budget per episode, T0 an initial tank level).")
@click.option("--json", "as_json", is_flag=True, help="Print the certificate as JSON.")
def certify(kr_range: str, br_range: str, kl: float, bl: float, tl_max: float, tr_max: float,
            method: str, variation: str, as_json: bool) -> int:
    """Certify that every remote gain in the ranges is stable for the delay bounds."""
    from dataclasses import replace

    from teleopkit.certification import (
        best_certificate,
        certify_gains,
        methods_for,
        parse_gain_variation,
    )
    from teleopkit.certification.gain_sets import GainBox, parse_range
    from teleopkit.certification.report import certificate_table
    from teleopkit.model.params import PDGains, paper_setup

    params = replace(paper_setup(), local_gains=PDGains.uniform(kl, bl))
    box = GainBox.uniform(parse_range(kr_range, "--kr"), parse_range(br_range, "--br"))
    gain_variation = parse_gain_variation(variation)
    results = [certify_gains(params, box, tl_max, tr_max, name, gain_variation)
               for name in methods_for(method, gain_variation)]
    best = best_certificate(results)
    if as_json:
        import json

        payload = best.to_dict()
        payload["results"] = [c.to_dict() for c in results]
        click.echo(json.dumps(payload, indent=2))
    else:
        click.echo(certificate_table(results))
    return 0 if best.certified else 1


def _single_thread() -> None:
    """One torch thread: the second core belongs to the simulator or to other work."""
    import torch

    torch.set_num_threads(1)


CERTIFICATE_OPTION = click.option(
    "--certificate", type=click.Path(dir_okay=False, path_type=Path), default=None,
    help="Gain certificate (JSON of teleopkit certify --json) whose set the safety layer "
         "projects onto [default: the closed form on K_r in [1, 50], B_r in [1, 150], T* = 1 s].")


def _env_config(certificate: Path | None, duration: float) -> FlexTeleopConfig:
    """Environment settings with the certificate read from ``certificate`` (if given)."""
    from teleopkit.certification import GainCertificate
    from teleopkit.rl.env import FlexTeleopConfig

    loaded = None if certificate is None else GainCertificate.from_json(certificate.read_text())
    return FlexTeleopConfig(certificate=loaded, episode_length=duration)


@cli.command("train")
@click.option("--steps", type=click.IntRange(min=1), default=1_600_000, show_default=True,
              help="Transitions to collect over all environments (rounded up to whole "
                   "episodes of every environment).")
@click.option("--envs", type=click.IntRange(min=1), default=16, show_default=True,
              help="Scenarios simulated together.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Master seed of the run.")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("runs/train"), show_default=True,
              help="Directory for checkpoint.pt, train_log.csv, policy.npz, best_policy.npz "
                   "and config.json.")
@click.option("--resume", is_flag=True, help="Continue the checkpoint in --out.")
@CERTIFICATE_OPTION
def train_command(steps: int, envs: int, seed: int, out: Path, resume: bool,
                  certificate: Path | None) -> None:
    """Train a TD3 gain tuner (checkpointed every episode; --resume continues exactly).

    The other settings are the defaults of teleopkit.rl.training.TrainConfig: 40 s episodes, the
    paper's TD3 with learning rates 1e-3, best policy kept by validation cost.
    """
    from teleopkit.rl.training import TrainConfig, train

    _single_thread()
    config = TrainConfig(total_steps=steps, num_envs=envs, seed=seed,
                         learning_starts=max(envs, min(TrainConfig.learning_starts, steps)))
    result = train(config, out, resume=resume, env_config=_env_config(certificate, 40.0))
    row = result.log.iloc[-1]
    click.echo(f"trained {int(row['step'])} steps; best validation cost "
               f"{result.log['validation_cost'].min():.5g}; policies in {out}")


def _best_static(policies: Sequence[GainPolicy], config: FlexTeleopConfig) -> np.ndarray:
    """Best static gains stored with the first policy, or found now in the config's set."""
    from teleopkit.rl.baselines import best_static_gains

    stored = policies[0].metadata.get("best_static_gains")
    if stored is not None and config.certificate is None:
        return np.asarray(stored, dtype=float)
    click.echo("searching the best static certified gains (about a minute) ...", err=True)
    return best_static_gains(config=config).gains


def _compare(policies: Sequence[GainPolicy], scenarios: int, seed: int, config: FlexTeleopConfig,
             out: Path) -> pd.DataFrame:
    """Evaluate TD3, fixed and best static gains; write the report; return the summary."""
    from teleopkit.rl.baselines import fixed_gains
    from teleopkit.rl.evaluation import ConstantGains, evaluate, save_report, to_markdown

    controllers: dict[str, Controller | list[Controller]] = {
        "TD3": list(policies), "fixed": ConstantGains(fixed_gains()),
        "best static": ConstantGains(_best_static(policies, config))}
    per_scenario = evaluate(controllers, scenarios, seed, config)
    summary = save_report(per_scenario, out, baseline="best static")
    click.echo(to_markdown(summary, baseline="best static"), nl=False)
    return summary


@cli.command("evaluate")
@click.option("--policy", "policy_files", required=True, multiple=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Policy file (policy.npz); repeat for several training seeds.")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios.")
@click.option("--seed", type=click.IntRange(min=0), default=7_777, show_default=True,
              help="Seed of the held-out scenarios (teleopkit.rl.evaluation.EVAL_SEED).")
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=40.0,
              show_default=True, help="Episode length [s].")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("runs/evaluate"), show_default=True,
              help="Directory for per_scenario.csv, summary.csv and summary.md.")
@CERTIFICATE_OPTION
def evaluate_command(policy_files: tuple[Path, ...], scenarios: int, seed: int,
                     duration: float, out: Path, certificate: Path | None) -> int:
    """Compare TD3 policies with fixed and best static certified gains on held-out scenarios."""
    from teleopkit.rl.policy import GainPolicy

    _single_thread()
    policies = [GainPolicy.load(path) for path in policy_files]
    summary = _compare(policies, scenarios, seed, _env_config(certificate, duration), out)
    unsafe = int(summary["unsafe_actions"].sum())
    click.echo(f"report in {out}; unsafe actions: {unsafe}")
    return 0 if unsafe == 0 else 1


@cli.command("reproduce")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("runs/reproduce"), show_default=True,
              help="Directory for the figures (PNG) and the comparison table.")
@click.option("--scenarios", type=click.IntRange(min=1), default=32, show_default=True,
              help="Held-out scenarios of the comparison table.")
def reproduce_command(out: Path, scenarios: int) -> int:
    """Paper figures and comparison table from the shipped pretrained policy (no training)."""
    from teleopkit.plots import save_paper_figures
    from teleopkit.rl.evaluation import EVAL_SEED, ConstantGains, rollout
    from teleopkit.rl.policy import GainPolicy

    _single_thread()
    policy = GainPolicy.pretrained()
    config = _env_config(None, 40.0)
    summary = _compare([policy], scenarios, EVAL_SEED, config, out)
    runs = {"TD3": rollout(policy, 1, EVAL_SEED).to_frame(),
            "best static": rollout(ConstantGains(_best_static([policy], config)), 1,
                                   EVAL_SEED).to_frame()}
    paths = save_paper_figures(runs, out)
    unsafe = int(summary["unsafe_actions"].sum())
    click.echo(f"wrote {len(paths)} figures and the table to {out}; unsafe actions: {unsafe}")
    return 0 if unsafe == 0 else 1

def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit code (bad input: 2, one line, no traceback).

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments; ``sys.argv[1:]`` by default.

    Returns
    -------
    int
        The exit code.
    """
    try:
        result = cli.main(args=list(argv) if argv is not None else None, prog_name="teleopkit",
                          standalone_mode=False)
    except click.exceptions.Exit as done:
        return int(done.exit_code)
    except click.ClickException as error:
        click.echo(f"teleopkit: error: {error.format_message()}", err=True)
        return 2
    except (ValueError, OSError) as error:
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        click.echo(f"teleopkit: error: {message}", err=True)
        return 2
    except click.exceptions.Abort:
        click.echo("teleopkit: aborted", err=True)
        return 1
    return int(result) if isinstance(result, int) else 0



def _campaign_client(workers: int | None, scheduler: str | None) -> str | None:
    """The ``client`` of :func:`~teleopkit.robustness.campaign.run_campaign` from the options."""
    if scheduler is not None and workers is not None:
        raise click.UsageError("--workers sizes the local cluster; it cannot be combined with "
                               "--scheduler")
    if scheduler is not None and not scheduler.strip():
        raise click.BadParameter("--scheduler needs an address such as tcp://HOST:8786")
    return scheduler


@cli.command("campaign")
@click.argument("spec", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Result table, .parquet or .csv (finished chunks are kept in OUT.chunks/).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local Dask cluster [default: every usable core].")
@click.option("--scheduler", default=None,
              help="Address of a running Dask scheduler (tcp://HOST:8786) instead of a local "
                   "cluster, or 'synchronous' to run in this process.")
@click.option("--chunk", type=click.IntRange(min=1), default=64, show_default=True,
              help="Scenarios per task, simulated as one batch.")
@click.option("--resume", is_flag=True,
              help="Continue the campaign whose chunks are in OUT.chunks/ (only missing chunks "
                   "run).")
def campaign_command(spec: Path, out: Path, workers: int | None, scheduler: str | None,
                     chunk: int, resume: bool) -> int:
    """Run a robustness campaign (YAML, JSON or TOML SPEC) on Dask; one row per scenario."""
    import time

    from teleopkit.robustness.campaign import CampaignInterrupted, run_campaign
    from teleopkit.robustness.spec import CampaignSpec

    client = _campaign_client(workers, scheduler)
    loaded = CampaignSpec.from_file(spec)
    chunks = out.with_name(out.name + ".chunks")
    if not resume and any(chunks.glob("chunk-*.parquet")):
        raise click.UsageError(f"{chunks} holds chunks of an earlier run: pass --resume to "
                               "continue it, or delete it")
    start = time.perf_counter()
    try:
        table = run_campaign(loaded, out, client=client, chunk=chunk, resume=resume,
                             workers=workers, progress=sys.stderr.isatty())
    except (ImportError, CampaignInterrupted) as error:
        raise click.ClickException(str(error)) from None
    diverged = int(table["diverged"].sum())
    click.echo(f"wrote {len(table)} scenarios to {out} in {time.perf_counter() - start:.1f} s; "
               f"diverged: {diverged}")
    return 0


@cli.command("falsify")
@click.option("--kr", "kr_range", required=True, help="Range of K_r, MIN:MAX (every joint).")
@click.option("--br", "br_range", required=True, help="Range of B_r, MIN:MAX (every joint).")
@click.option("--tl-max", type=float, default=1.0, show_default=True,
              help="Forward delay bound T_l* [s].")
@click.option("--tr-max", type=float, default=1.0, show_default=True,
              help="Backward delay bound T_r* [s].")
@click.option("--method", type=click.Choice(["nuno", "lmi"]), default="nuno", show_default=True,
              help="Certificate whose set is searched (lmi: minutes for two joints).")
@click.option("--gain-variation", "variation", default="frozen", show_default=True,
              help="Gain class of the certificate: frozen | switching | rate:R | scheduled:L | "
                   "tank[:T0].")
@click.option("--switch-gains/--certified-gains", "switch_gains", default=None,
              help="Let the adversary switch gains even if the certificate covers frozen gains "
                   "only (a probe outside the certificate) [default: as the certificate].")
@click.option("--delays", type=click.Choice(["square", "segments"]), default="square",
              show_default=True, help="Adversarial delay pattern.")
@click.option("--objective",
              type=click.Choice(["energy_growth", "error_growth", "energy", "storage"]),
              default="energy_growth", show_default=True, help="What the adversary maximises.")
@click.option("--search", "search_method", type=click.Choice(["cma", "random"]), default="cma",
              show_default=True, help="CMA-ES or random search.")
@click.option("--budget", type=click.IntRange(min=2), default=256, show_default=True,
              help="Runs to simulate.")
@click.option("--population", type=click.IntRange(min=2), default=16, show_default=True,
              help="Runs per generation (one simulator batch).")
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=20.0,
              show_default=True, help="Seconds per run.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the search.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CSV file for the worst run's trajectory.")
def falsify_command(kr_range: str, br_range: str, tl_max: float, tr_max: float, method: str,
                    variation: str, switch_gains: bool | None, delays: str, objective: str,
                    search_method: str, budget: int, population: int, duration: float,
                    seed: int, out: Path | None) -> int:
    """Search the worst adversarial delays and gains in a certified set (exit 1: a run diverged)."""
    from teleopkit.certification import certify_gains
    from teleopkit.certification.gain_sets import GainBox, parse_range
    from teleopkit.model.params import paper_setup
    from teleopkit.robustness.adversary import SearchSpace
    from teleopkit.robustness.search import search

    params = paper_setup()
    box = GainBox.uniform(parse_range(kr_range, "--kr"), parse_range(br_range, "--br"))
    certificate = certify_gains(params, box, tl_max, tr_max, method, variation)
    space = SearchSpace(params, certificate, switch_gains, delays, duration=duration)
    try:
        result = search(space, objective, search_method, budget,  # type: ignore[arg-type]
                        population, seed)
    except ImportError as error:
        raise click.ClickException(str(error)) from None
    if out is not None:
        try:
            result.trajectory.to_csv(out, index=False)
        except OSError as error:
            raise click.FileError(str(out), hint=error.strerror) from None
    click.echo(result.summary())
    if result.finding:
        click.echo("FINDING: a run inside the certified class diverged", err=True)
    return 1 if result.diverged else 0


if __name__ == "__main__":
    sys.exit(main())
