"""``teleopkit campaign`` and ``teleopkit falsify``: many scenarios, and the worst ones."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from teleopkit.cli.options import (
    FiniteFloat,
    check_output,
    check_traces,
    gain_variation,
    run_duration,
    setup_option,
)

if TYPE_CHECKING:
    from teleopkit.setup import Setup

__all__ = ["campaign_command", "falsify_command"]

_SPEC_FORMAT = """\b
Spec format (YAML; JSON and TOML files hold the same keys):
  mode: grid            # grid (every combination) or random (then samples: N)
  duration: 40          # seconds per scenario; also seed, dt, control_period,
                        # divergence_radius
  factors:              # a value, a list, {linspace: [LO, HI, N]}, {range: [A, B]};
                        # random mode also {uniform: [LO, HI]}, {loguniform: [LO, HI]}
    delay: [paper, "constant:500ms", "switching:0:1:50ms", "csv:trace.csv"]
    joint_stiffness: [50, 100, 200]
    kr: [5, 10, 20]
    br: 30
    controller: [fixed, "policy:td3.npz"]
    seed: {range: [0, 8]}
\b
Factors: joint_stiffness, rotor_inertia, remote_mass_scale, local_mass_scale, kl, bl, delay,
delay_scale, reference_gain, kr, br, seed, controller (every one is a column of the result).
"""


def _client(workers: int | None, scheduler: str | None) -> str | None:
    """The ``client`` of :func:`~teleopkit.robustness.campaign.run_campaign` from the options."""
    if scheduler is not None and workers is not None:
        raise click.UsageError("--workers sizes the local cluster; it cannot be combined with "
                               "--scheduler")
    if scheduler is not None and not scheduler.strip():
        raise click.BadParameter("needs an address such as tcp://HOST:8786, or synchronous",
                                 param_hint="'--scheduler'")
    return scheduler


@click.command("campaign", epilog=_SPEC_FORMAT)
@click.argument("spec", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True,
              help="Result table, .parquet or .csv (finished chunks are kept in OUT.chunks/).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local Dask cluster [default: every usable core].")
@click.option("--scheduler", default=None,
              help="Address of a running Dask scheduler (tcp://HOST:8786) instead of a local "
                   "cluster, or 'synchronous' to run in this process (no Dask needed).")
@click.option("--chunk", type=click.IntRange(min=1), default=64, show_default=True,
              help="Scenarios per task, simulated as one batch.")
@click.option("--resume", is_flag=True,
              help="Continue the campaign whose chunks are in OUT.chunks/ (only missing chunks "
                   "run).")
@setup_option
@click.pass_context
def campaign_command(ctx: click.Context, spec: Path, out: Path, workers: int | None,
                     scheduler: str | None, chunk: int, resume: bool, setup: Setup) -> int:
    """Run a robustness campaign (YAML, JSON or TOML SPEC) on Dask; one row per scenario.

    The factors vary a setup: --setup FILE, else the spec's key setup, else the paper's.
    """
    import time
    from dataclasses import replace

    from click.core import ParameterSource

    from teleopkit.robustness.campaign import CampaignInterrupted, run_campaign
    from teleopkit.robustness.spec import CampaignSpec
    from teleopkit.robustness.store import ChunkStore

    client = _client(workers, scheduler)
    check_output(out, "--out", (".parquet", ".csv"))
    loaded = CampaignSpec.from_file(spec)
    given = ctx.get_parameter_source("setup") is not ParameterSource.DEFAULT
    if given:
        loaded = replace(loaded, setup=setup)
    if "setup" in map(str, loaded.factor("delay").levels):  # rows that draw the network's delays
        check_traces(loaded.setup, loaded.duration, "--setup" if given else "SPEC")
    store = ChunkStore(out)
    if not resume and store.has_chunks():
        raise click.UsageError(f"{store.dir} holds chunks of an earlier run: pass --resume to "
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


@click.command("falsify")
@click.option("--kr", "kr_range", required=True, help="Range of K_r, MIN:MAX (every joint).")
@click.option("--br", "br_range", required=True, help="Range of B_r, MIN:MAX (every joint).")
@click.option("--tl-max", type=FiniteFloat(min=0, min_open=True), default=None,
              help="Forward delay bound T_l* [s] [default: the setup's network.forward.max].")
@click.option("--tr-max", type=FiniteFloat(min=0, min_open=True), default=None,
              help="Backward delay bound T_r* [s] [default: the setup's "
                   "network.backward.max].")
@click.option("--method", type=click.Choice(["nuno", "lmi"]), default="nuno", show_default=True,
              help="Certificate whose set is searched (lmi: minutes for two joints).")
@click.option("--gain-variation", "variation", default="frozen", show_default=True,
              callback=gain_variation,
              help="Gain class of the certificate: frozen | switching | rate:R | scheduled:L | "
                   "tank[:T0 or :Drad].")
@click.option("--switch-gains/--certified-gains", "switch_gains", default=None,
              help="Let the adversary switch gains even if the certificate covers frozen gains "
                   "only (a probe outside the certificate) [default: as the certificate].")
@click.option("--delays", type=click.Choice(["square", "segments"]), default="square",
              show_default=True, help="Adversarial delay pattern.")
@click.option("--objective",
              type=click.Choice(["energy_growth", "error_growth", "energy", "storage"]),
              default="energy_growth", show_default=True,
              help="What the adversary maximises (storage: scheduled classes).")
@click.option("--search", "search_method", type=click.Choice(["cma", "random"]), default="cma",
              show_default=True, help="CMA-ES or random search.")
@click.option("--budget", type=click.IntRange(min=2), default=256, show_default=True,
              help="Runs to simulate (whole populations).")
@click.option("--population", type=click.IntRange(min=2), default=16, show_default=True,
              help="Runs per generation (one simulator batch).")
@click.option("--duration", type=float, default=20.0, show_default=True, callback=run_duration,
              help="Seconds per run (a whole number of 10 ms control periods).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the search.")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="CSV file for the worst run's trajectory.")
@setup_option
def falsify_command(kr_range: str, br_range: str, tl_max: float | None, tr_max: float | None,
                    method: str, variation: object, switch_gains: bool | None, delays: str,
                    objective: str, search_method: str, budget: int, population: int,
                    duration: float, seed: int, out: Path | None, setup: Setup) -> int:
    """Search the worst delays and gains in a certified set (exit 1: diverged or over its bound).

    The set is certified for the setup's plant (--setup; the paper's by default).
    """
    from teleopkit.certification import certify_gains
    from teleopkit.certification.gain_sets import GainBox, parse_range
    from teleopkit.robustness.adversary import SearchSpace
    from teleopkit.robustness.search import search

    if budget < population:
        raise click.BadParameter(f"{budget} runs are fewer than one population of "
                                 f"{population} (--population)", param_hint="'--budget'")
    if out is not None:
        check_output(out, "--out", (".csv",))
    params = setup.params
    box = GainBox.uniform(parse_range(kr_range, "--kr"), parse_range(br_range, "--br"),
                          setup.n_joints)
    forward, backward = setup.network.bounds
    certificate = certify_gains(params, box, forward if tl_max is None else tl_max,
                                backward if tr_max is None else tr_max, method, variation)
    space = SearchSpace(params, certificate, switch_gains, delays, duration=duration)
    result = search(space, objective, search_method, budget,  # type: ignore[arg-type]
                    population, seed)
    if out is not None:
        result.trajectory.to_csv(out, index=False)
    click.echo(result.summary())
    if result.finding:
        click.echo("FINDING: a run inside the certified class diverged or exceeded its storage "
                   "bound", err=True)
    return 1 if result.finding or result.diverged else 0
