"""Paper-style figures of a simulated run (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.figure import Figure

__all__ = ["plot_run", "save_run_figure"]


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
    fig, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True, layout="constrained")
    t = table["t"]
    axes[0].plot(t, table["Tl"], label=r"$T_l$ (forward)")
    axes[0].plot(t, table["Tr"], label=r"$T_r$ (backward)")
    axes[0].set_ylabel("delay [s]")
    for i in range(1, n + 1):
        line = axes[1].plot(t, table[f"theta_{i}"], label=rf"$\theta_{{r,{i}}}$")[0]
        axes[1].plot(t, table[f"ql_delayed_{i}"], "--", color=line.get_color(),
                     label=rf"$q_{{l,{i}}}(t - T_l)$")
        axes[2].plot(t, table[f"e_track_{i}"], label=f"joint {i}")
        axes[3].plot(t, table[f"e_damp_{i}"], label=f"joint {i}")
    axes[1].set_ylabel("position [rad]")
    axes[2].set_ylabel("tracking error [rad]")
    axes[3].set_ylabel("damping error [rad]")
    axes[3].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize="small", ncol=2)
    if title:
        fig.suptitle(title)
    return fig


def save_run_figure(table: pd.DataFrame, path: str | Path, title: str = "") -> None:
    """Draw :func:`plot_run` into an image file (format from the suffix, e.g. ``.png``)."""
    fig = plot_run(table, title)
    fig.savefig(path, dpi=110)
    plt.close(fig)
