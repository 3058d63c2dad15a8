"""``teleopkit simulate``: one run of a setup's teleoperator, as CSV and a figure."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from teleopkit.cli.options import (
    DELAY_SPECS,
    IMAGE_SUFFIXES,
    check_disk,
    check_output,
    delay_spec,
    dt_option,
    gains,
    run_duration,
    setup_option,
)
from teleopkit.model.plant_range import value_of
from teleopkit.model.records import PLANT_LABELS
from teleopkit.setup.reading import listed
from teleopkit.sim.timing import CONTROL_PERIOD

if TYPE_CHECKING:
    from teleopkit.setup import Setup
    from teleopkit.sim.trajectory import Trajectory

__all__ = ["simulate_command"]

_CSV_ROW_BYTES = 27 * 22
"""About what one row of the run's CSV takes (27 columns of shortest round-trip floats)."""


@click.command("simulate")
@click.option("--kr", required=True, callback=gains,
              help="Remote proportional gain K_r: one value or K1,K2.")
@click.option("--br", required=True, callback=gains,
              help="Remote damping gain B_r: one value or B1,B2.")
@click.option("--duration", type=float, default=40.0, show_default=True, callback=run_duration,
              help="Seconds (a whole number of 10 ms control periods).")
@click.option("--delay", default=None, callback=delay_spec,
              help=f"Delays of both channels: {DELAY_SPECS} [default: the setup's network].")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of what the setup draws: operator motion, delays, start.")
@dt_option
@click.option("--out", type=click.Path(path_type=Path), required=True,
              help="CSV file for the trajectory.")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help=f"Figure file ({', '.join(IMAGE_SUFFIXES)}) of the run, paper style.")
@setup_option
def simulate_command(kr: list[float], br: list[float], duration: float, delay: str | None,
                     seed: int, dt: float, out: Path, plot: Path | None, setup: Setup) -> int:
    """Simulate a setup's teleoperator (the paper's by default) with constant remote gains.

    The run is written as CSV (and a figure with --plot). Exit 1: the run diverged (its state
    stopped being finite or a position passed 20 rad); its CSV is written, no figure.
    """
    from teleopkit.files import write_csv
    from teleopkit.sim.divergence import Divergence

    check_output(out, "--out", (".csv",))
    if plot is not None:
        check_output(plot, "--plot", IMAGE_SUFFIXES)
    check_disk(out, int(round(duration / CONTROL_PERIOD) + 1) * _CSV_ROW_BYTES, "--out")
    n = setup.n_joints
    action = np.array([*_per_joint(kr, n, "--kr"), *_per_joint(br, n, "--br")])
    trajectory = _run(action, duration, delay, seed, dt, setup)
    write_csv(out, trajectory.columns())
    diverged = Divergence().describe(trajectory.t, trajectory.state)
    if diverged is not None:
        click.echo(f"wrote {len(trajectory.t)} rows to {out}; {diverged}")
        _warn_beyond_margin(setup, action, float(trajectory.delays.max()))
        return 1
    if plot is not None:
        from teleopkit.plots import save_run_figure

        save_run_figure(trajectory.to_frame(), plot,
                        title=f"K_r = {kr}, B_r = {br}, {_delay_title(setup, delay)}")
    e = trajectory.e_track[:, 0]
    rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    click.echo(f"wrote {len(trajectory.t)} rows to {out}{_drawn_plant(setup, seed, delay)}; "
               f"RMS tracking error {rms:.4g} rad")
    _warn_beyond_margin(setup, action, float(trajectory.delays.max()))
    return 0


def _run(action: np.ndarray, duration: float, delay: str | None, seed: int, dt: float,
         setup: Setup) -> Trajectory:
    """The run, without the Python warning of a divergence (the command says it, exit 1)."""
    import warnings

    from teleopkit.sim.divergence import DivergenceWarning
    from teleopkit.sim.simulator import simulate_trajectory

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DivergenceWarning)
        return simulate_trajectory(action, duration=duration, delay=delay, seed=seed, dt=dt,
                                   setup=setup)


def _delay_title(setup: Setup, delay: str | None) -> str:
    """The run's delays for a figure title: both directions, ``forward / backward`` if they differ.

    ``delay`` (the option) drives both; else each direction is the setup's network's.
    """
    directions = [delay] * 2 if delay else [", ".join(channel.profiles) for channel in
                                            (setup.network.forward, setup.network.backward)]
    spec = directions[0] if directions[0] == directions[1] else " / ".join(directions)
    words = "delay" if directions[0] == directions[1] else "delays (forward / backward)"
    scaled = (" (the paper's profile scaled by this seed's delay scales)"
              if "paper" in directions else "")
    return f"{words} {spec}{scaled}"


def _drawn_plant(setup: Setup, seed: int, delay: str | None) -> str:
    """Which plant the seed drew, and its ranged values (empty for one fixed plant)."""
    if not (setup.other_plants or setup.plant_ranges):
        return ""
    scenario = setup.scenarios(seed, 1, delay)
    drawn = scenario.plants[scenario.plant_of[0]]
    k = next(k for k, (params, interval) in enumerate(zip(setup.plants, setup.ranges,
                                                          strict=True))
             if interval.covers(params, drawn))
    parts = [f"plant {k + 1} of {len(setup.plants)}"] if setup.other_plants else []
    parts += [f"{PLANT_LABELS[name]} {listed(value_of(drawn, name))}"
              for name in setup.ranges[k].bounds]
    return f" ({'; '.join(parts)})"


def _per_joint(values: list[float], n: int, option: str) -> list[float]:
    """One gain per joint: a single value repeated, or ``n`` values."""
    if len(values) == 1:
        return values * n
    if len(values) != n:
        wanted = "1 value (the setup has one joint)" if n == 1 else \
            f"1 or {n} values (one per joint)"
        raise click.BadParameter(f"needs {wanted}, got {len(values)}", param_hint=f"'{option}'")
    return values


def _warn_beyond_margin(setup: Setup, gains: np.ndarray, longest: float) -> None:
    """One line on standard error when the run's delays exceed what its gains are certified for.

    ``simulate`` runs any gains (it is a simulator, not a safety layer); ``train``, ``evaluate``
    and ``campaign`` refuse a certificate whose delay bound the delays can exceed.
    """
    from teleopkit.certification.nuno.condition import nuno_joint_margins

    margin = min(float(nuno_joint_margins(params, gains).min()) for params in setup.plants)
    if longest > margin:
        click.echo(f"warning: the delays reached {longest:.4g} s; these gains are certified "
                   f"(closed form, constant gains) for delays up to {margin:.4g} s only, so this "
                   "run is outside every certificate", err=True)
