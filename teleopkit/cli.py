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
@click.option("--dt", type=float, default=0.0025, show_default=True, help="Integration step [s].")
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
