"""``teleopkit search-law``: a gain law (measured levels to gains) searched by CMA-ES."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from teleopkit.cli.options import (
    FiniteFloat,
    certificate_option,
    check_covers_setup,
    check_output_dir,
    check_setup_step,
    check_traces,
    dt_option,
    gain_variation,
    read_certificate,
    setup_option,
)

if TYPE_CHECKING:
    import pandas as pd

    from teleopkit.certification.gain_certificate import GainCertificate
    from teleopkit.setup import Setup

__all__ = ["search_law_command"]


@click.command("search-law")
@click.option("--generations", type=click.IntRange(min=1), default=40, show_default=True,
              help="CMA-ES generations.")
@click.option("--population", type=click.IntRange(min=2), default=15, show_default=True,
              help="Laws per generation.")
@click.option("--scenarios", type=click.IntRange(min=1), default=64, show_default=True,
              help="Fresh scenarios per generation, shared by the laws and the start gains.")
@click.option("--harm", type=FiniteFloat(min=0), default=1.0, show_default=True,
              help="Weight of the mean excess cost over the start gains (0: the mean relative "
                   "cost alone).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the scenarios and of CMA-ES.")
@click.option("--out", type=click.Path(path_type=Path), default="runs/law", show_default=True,
              help="Directory for best_policy.npz, search_log.csv and config.json.")
@click.option("--gain-variation", "variation", default=None, callback=gain_variation,
              help="Gain class of the law, on the closed form's certificate of the default box "
                   "for the delays the setup's network reaches [default: "
                   "teleopkit.rl.env.COVERING_CLASS].")
@certificate_option
@dt_option
@setup_option
def search_law_command(generations: int, population: int, scenarios: int, harm: float,
                       seed: int, out: Path, variation: object, certificate: Path | None,
                       dt: float, setup: Setup) -> None:
    """Search a gain law for the setup: measured levels of motion and errors to remote gains.

    The law reads the adaptive observation's levels (how much the operator moves, how large
    both errors are), the measured delay and the safety layer's state, through one linear
    layer, starting from the best constant gains of the class for the setup (searched first,
    about a minute); CMA-ES then runs every generation's laws and the start gains on the same
    fresh scenarios of the setup (teleopkit.rl.law_search). Every gain is projected by the
    safety layer; the result is a policy file that evaluate runs like any tuner. The start
    gains (the law with zero weights) are a candidate too: when no law beats them on the
    validation scenarios, they are what is saved, and a warning says so.
    """
    from teleopkit.rl.env import FlexTeleopConfig
    from teleopkit.rl.law_search import LawSearchConfig, law_start, search_gain_law

    check_output_dir(out, "--out")
    check_traces(setup, FlexTeleopConfig.episode_length, "--setup")  # the laws' episodes
    check_setup_step(setup, dt)
    chosen = _law_certificate(variation, certificate, setup)
    config = FlexTeleopConfig(setup, chosen, observation="adaptive", dt=dt)
    settings = LawSearchConfig(generations=generations, population=population,
                               scenarios=scenarios, harm=harm, seed=seed)
    click.echo(f"searching a gain law under {chosen.gain_variation} for the setup "
               f"(setup fingerprint {setup.fingerprint})", err=True)
    start = law_start(config, progress=None)
    click.echo("start: the best constant gains of the class "
               f"{[round(float(g), 4) for g in start]}", err=True)
    result = search_gain_law(start, settings, config, out_dir=out, progress=None)
    _report(result.log, out / "best_policy.npz")


def _report(log: pd.DataFrame, saved: Path) -> None:
    """The law kept, against the start gains; a warning line when no law beat them."""
    laws = log[log["generation"] > 0]
    found = laws.loc[laws["validation_objective"].idxmin()]
    kept = log.loc[log["validation_objective"].idxmin()]
    if kept["generation"] == 0:
        click.echo("warning: no law found beat the start gains on the validation scenarios "
                   f"(the best, at generation {int(found['generation'])}: objective "
                   f"{_percent(found)}, validation cost {found['validation_cost']:.5g} against "
                   f"{found['start_cost']:.5g}); {saved} holds the start gains themselves (the "
                   "law with zero weights)", err=True)
    elif kept["validation_cost"] > kept["start_cost"]:
        click.echo("warning: the law kept costs more on the validation scenarios than the start "
                   f"gains on average ({kept['validation_cost']:.5g} against "
                   f"{kept['start_cost']:.5g}) though less relative to them per scenario (the "
                   "search's objective): it wins the cheap scenarios and loses the dear ones",
                   err=True)
    if kept["generation"] == 0:
        click.echo(f"kept the start gains (generation 0): validation cost "
                   f"{kept['validation_cost']:.5g}; law in {saved}")
        return
    click.echo(f"best law at generation {int(kept['generation'])}: validation cost "
               f"{kept['validation_cost']:.5g} against {kept['start_cost']:.5g} for the start "
               f"gains (objective {_percent(kept)}: the cost relative to theirs per scenario, "
               f"plus the excess where dearer); law in {saved}")


def _percent(row: pd.Series) -> str:
    """A log row's validation objective as a change in percent (0 % for the start gains)."""
    return f"{100 * (row['validation_objective'] - 1):+.1f} %"


def _law_certificate(variation: object, certificate: Path | None,
                     setup: Setup) -> GainCertificate:
    """The certificate asked for (file or class), checked against the setup."""
    from teleopkit.certification.certifier import default_certificate
    from teleopkit.rl.env import COVERING_CLASS
    from teleopkit.safety.factory import layer_for

    if certificate is not None and variation is not None:
        raise click.BadParameter("give a --certificate or a --gain-variation, not both",
                                 param_hint="'--gain-variation'")
    chosen = (read_certificate(certificate) if certificate is not None else
              default_certificate(setup.params, setup.network.reached_bounds,
                                  variation or COVERING_CLASS,  # type: ignore[arg-type]
                                  setup.plants, setup.ranges, setup.start))
    check_covers_setup(chosen, setup, None, "the --certificate")
    layer_for(chosen)  # refuses a certificate whose set is not certified, before any work
    return chosen
