"""Order of the tutorials in the sphinx-gallery index (referenced by name from ``conf.py``)."""

from __future__ import annotations

from pathlib import Path

ORDER = (
    "plot_simulate.py",
    "plot_certify.py",
    "plot_scheduled_gains.py",
    "plot_methods_vs_spectrum.py",
    "plot_delay_trace.py",
    "plot_gymnasium.py",
    "plot_train_tuner.py",
    "plot_other_rl_library.py",
    "plot_own_robot.py",
)
"""Tutorials in reading order; any other tutorial follows them, sorted by file name."""


class TutorialOrder:
    """Sort key: the files of :data:`ORDER` first, in that order, then the rest by name.

    Parameters
    ----------
    src_dir : str or pathlib.Path
        The gallery's source directory (passed by sphinx-gallery, unused).
    """

    def __init__(self, src_dir: str | Path) -> None:
        self.src_dir = src_dir

    def __call__(self, filename: str | Path) -> tuple[int, str]:
        """Return the sort key of ``filename``."""
        name = Path(filename).name
        return (ORDER.index(name) if name in ORDER else len(ORDER), name)

    def __repr__(self) -> str:
        return "<TutorialOrder>"
