"""The ``teleopkit`` command line.

Exit codes: 0 success (or certified), 1 ran but the answer is negative (not certified), 2 bad input
with a one-line message on standard error and no traceback.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import click
import numpy as np

from teleopkit.simulator import DEFAULT_DT

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
    from teleopkit.simulator import simulate as run

    gains = np.array(_gain_vector(kr, "--kr") + _gain_vector(br, "--br"))
    table = run(gains, duration=duration, delay=delay, seed=seed, dt=dt)
    try:
        table.to_csv(out, index=False)
    except OSError as error:
        raise click.FileError(str(out), hint=error.strerror) from None
    if plot is not None:
        from teleopkit.plots import save_run_figure

        save_run_figure(table, plot, title=f"K_r = {kr}, B_r = {br}, delay {delay}")
    e = table.filter(like="e_track_").to_numpy()
    rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    click.echo(f"wrote {len(table)} rows to {out}; RMS tracking error {rms:.4g} rad")


@cli.command()
@click.option("--kr", "kr_range", required=True, help="Range of K_r, MIN:MAX (every joint).")
@click.option("--br", "br_range", required=True, help="Range of B_r, MIN:MAX (every joint).")
@click.option("--kl", type=float, default=25.0, show_default=True, help="Local gain K_l.")
@click.option("--bl", type=float, default=10.0, show_default=True, help="Local damping B_l.")
@click.option("--tl-max", type=float, default=1.0, show_default=True,
              help="Forward delay bound T_l* [s].")
@click.option("--tr-max", type=float, default=1.0, show_default=True,
              help="Backward delay bound T_r* [s].")
@click.option("--method", type=click.Choice(["nuno"]), default="nuno", show_default=True,
              help="Certification method (the closed form of Nuño et al.).")
@click.option("--gain-variation", "variation", default="frozen", show_default=True,
              help="frozen | switching | rate:R (R in gain units per second).")
@click.option("--json", "as_json", is_flag=True, help="Print the certificate as JSON.")
def certify(kr_range: str, br_range: str, kl: float, bl: float, tl_max: float, tr_max: float,
            method: str, variation: str, as_json: bool) -> int:
    """Certify that every remote gain in the ranges is stable for the delay bounds."""
    from dataclasses import replace

    from teleopkit.certification import certify_gains, parse_gain_variation
    from teleopkit.gains import GainBox, parse_range
    from teleopkit.params import PDGains, paper_setup
    from teleopkit.report import certificate_table

    params = replace(paper_setup(), local_gains=PDGains.uniform(kl, bl))
    box = GainBox.uniform(parse_range(kr_range, "--kr"), parse_range(br_range, "--br"))
    gain_variation = parse_gain_variation(variation)
    results = [certify_gains(params, box, tl_max, tr_max, method, gain_variation)]
    best = max(results, key=lambda c: (c.certified, c.delay_margin))
    if as_json:
        import json

        payload = best.to_dict()
        payload["results"] = [c.to_dict() for c in results]
        click.echo(json.dumps(payload, indent=2))
    else:
        click.echo(certificate_table(results))
    return 0 if best.certified else 1


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


if __name__ == "__main__":
    sys.exit(main())
