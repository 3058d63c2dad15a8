"""Paper-style figures of a simulated run (matplotlib, no display needed)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.figure import Figure

__all__ = ["plot_run", "save_paper_figures", "save_run_figure"]


_LINE_STYLES = ("-", "--", ":", "-.")
"""Line styles of the joints (or runs) that share a panel, in order."""


def _joints(table: pd.DataFrame) -> int:
    return sum(1 for c in table.columns if c.startswith("e_track_"))


def plot_run(table: pd.DataFrame, title: str = "") -> Figure:
    """Draw the delays, ``theta_r`` against ``q_l(t - T_l)``, and the tracking and damping errors.

    Parameters
    ----------
    table : pandas.DataFrame
        A run as returned by :func:`teleopkit.simulate` (or read back from its CSV).
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        A figure with four panels.
    """
    n = _joints(table)
    fig, axes = plt.subplots(4, 1, figsize=(9.5, 10), sharex=True, layout="constrained")
    t = table["t"]
    axes[0].plot(t, table["Tl"], label=r"$T_l$ (forward)")
    axes[0].plot(t, table["Tr"], label=r"$T_r$ (backward)")
    axes[0].set_ylabel("delay [s]")
    for i in range(1, n + 1):
        line = axes[1].plot(t, table[f"theta_{i}"], label=rf"$\theta_{{r,{i}}}$")[0]
        axes[1].plot(t, table[f"ql_delayed_{i}"], "--", color=line.get_color(),
                     label=rf"$q_{{l,{i}}}(t - T_l)$")
        # joints stay apart where they meet: a style each, joint 1 drawn on top
        style = {"ls": _LINE_STYLES[(i - 1) % len(_LINE_STYLES)], "zorder": 2 + n - i,
                 "lw": 1.6 if i == 1 else 1.0, "label": f"joint {i}"}
        axes[2].plot(t, table[f"e_track_{i}"], **style)
        axes[3].plot(t, table[f"e_damp_{i}"], **style)
    axes[1].set_ylabel("position [rad]")
    axes[2].set_ylabel("tracking error [rad]")
    axes[3].set_ylabel("damping error [rad]")
    axes[3].set_xlabel("time [s]")
    _legends_outside(axes)
    if title:
        fig.suptitle(title)
    return fig


def save_run_figure(table: pd.DataFrame, path: str | Path, title: str = "") -> None:
    """Draw :func:`plot_run` into an image file (format from the suffix, e.g. ``.png``).

    Parameters
    ----------
    table : pandas.DataFrame
        A run as returned by :func:`teleopkit.simulate`.
    path : str or Path
        Image file to write.
    title : str
        Figure title.
    """
    fig = plot_run(table, title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _figure(rows: int, title: str) -> tuple[Figure, list[Any]]:
    fig, axes = plt.subplots(rows, 1, figsize=(9.5, 2.6 * rows + 0.6), sharex=True,
                             layout="constrained", squeeze=False)
    fig.suptitle(title)
    return fig, list(axes[:, 0])


def _legends_outside(axes: Sequence[Any]) -> None:
    """A grid on every panel and its legend to the right of it, off the data."""
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
                  borderaxespad=0.0)


def _finish(fig: Figure, axes: list[Any], path: Path) -> Path:
    _legends_outside(axes)
    axes[-1].set_xlabel("time [s]")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _styles(runs: Mapping[str, pd.DataFrame]) -> list[tuple[str, pd.DataFrame, dict[str, Any]]]:
    """Name, table and line style of each run.

    The first is solid, thicker and drawn on top of the others (dashed, dotted), which would
    otherwise hide it where they agree.
    """
    return [(name, table, {"ls": _LINE_STYLES[i % len(_LINE_STYLES)],
                           "lw": 1.6 if i == 0 else 1.0, "zorder": 3 if i == 0 else 2,
                           "alpha": 1.0 if i == 0 else 0.8})
            for i, (name, table) in enumerate(runs.items())]


def save_paper_figures(runs: Mapping[str, pd.DataFrame], out_dir: str | Path) -> list[Path]:
    """The paper's result figures (Figs. 3-7) for one scenario, one PNG each.

    Parameters
    ----------
    runs : mapping of str to pandas.DataFrame
        Controller name to a run as returned by
        :meth:`teleopkit.rl.evaluation.Rollout.to_frame` (same scenario); the first is the main
        one (delay profile and positions are drawn for it).
    out_dir : str or Path
        Directory (created if needed).

    Returns
    -------
    list of Path
        ``delay_profile.png``, ``adaptive_gains.png``, ``positions.png``, ``tracking_error.png``
        and ``damping_error.png``.
    """
    directory = Path(out_dir)
    directory.mkdir(parents=True, exist_ok=True)
    main_name, main = next(iter(runs.items()))
    n = _joints(main)
    paths = []
    fig, axes = _figure(1, "Communication channel delay profile (the paper's profile, scaled by "
                           "the scenario's delay scales)")
    axes[0].plot(main["t"], main["Tl"], label=r"$T_l$ (forward)")
    axes[0].plot(main["t"], main["Tr"], label=r"$T_r$ (backward)")
    axes[0].set_ylabel("delay [s]")
    paths.append(_finish(fig, axes, directory / "delay_profile.png"))
    fig, axes = _figure(2, r"Remote gains: proportional $K_r^i$ and damping $B_r^i$")
    for name, table, style in _styles(runs):
        for i in range(1, n + 1):
            axes[0].plot(table["t"], table[f"Kr_{i}"], **style, label=f"{name}, joint {i}")
            axes[1].plot(table["t"], table[f"Br_{i}"], **style, label=f"{name}, joint {i}")
    axes[0].set_ylabel(r"$K_r$ [N m/rad]")
    axes[1].set_ylabel(r"$B_r$ [N m s/rad]")
    paths.append(_finish(fig, axes, directory / "adaptive_gains.png"))
    fig, axes = _figure(n, rf"{main_name}: $\theta_r^i(t)$ and $q_l^i(t - T_l)$")
    for i in range(1, n + 1):
        axes[i - 1].plot(main["t"], main[f"theta_{i}"], label=rf"$\theta_{{r,{i}}}$")
        axes[i - 1].plot(main["t"], main[f"ql_delayed_{i}"], "--",
                         label=rf"$q_{{l,{i}}}(t - T_l)$")
        axes[i - 1].set_ylabel("position [rad]")
    paths.append(_finish(fig, axes, directory / "positions.png"))
    for column, title, filename in (
            ("e_track", r"Tracking error $\theta_r - q_l(t - T_l)$", "tracking_error.png"),
            ("e_damp", r"Damping error $\theta_r - q_r$", "damping_error.png")):
        fig, axes = _figure(n, title)
        for name, table, style in _styles(runs):
            for i in range(1, n + 1):
                axes[i - 1].plot(table["t"], table[f"{column}_{i}"], **style, label=name)
                axes[i - 1].set_ylabel(f"joint {i} [rad]")
        paths.append(_finish(fig, axes, directory / filename))
    return paths
