"""Performance metrics of tracking and damping errors, over a whole run or streamed.

:func:`error_metrics` reduces recorded error signals; :class:`RunningMetrics` accumulates the
same RMS, IAE and maxima period by period (long runs of many scenarios need not be kept), with
the peak positions the divergence criterion (:mod:`teleopkit.sim.divergence`) reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from teleopkit.sim.divergence import Divergence, position_magnitude
from teleopkit.sim.state import StateLayout

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["Periods", "RunningMetrics", "error_metrics"]


class Periods(Protocol):
    """What :meth:`RunningMetrics.add` reads of simulated periods (a ``StepResult``)."""

    @property
    def t(self) -> np.ndarray:
        """End times of the periods ``(P,)``."""

    @property
    def state(self) -> np.ndarray:
        """States at those times ``(P, B, 12 n)``."""

    @property
    def delayed(self) -> np.ndarray:
        """Delayed signals ``(P, B, 2, n)``."""


def error_metrics(t: np.ndarray, errors: dict[str, np.ndarray]) -> pd.DataFrame:
    """RMS, integral of absolute error (IAE) and maximum of each error signal, per scenario.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Sample times.
    errors : dict of str to ndarray, shape (T, B, n)
        Named error signals (for example ``{"track": e_track, "damp": e_damp}``).

    Returns
    -------
    pandas.DataFrame
        One row per scenario, columns ``rms_<name>``, ``iae_<name>``, ``max_<name>`` computed on the
        Euclidean norm over joints (RMS and IAE by the trapezoidal rule over ``t``).
    """
    import pandas as pd  # tables only when asked for: ``teleopkit simulate`` needs none

    duration = float(t[-1] - t[0])
    columns: dict[str, np.ndarray] = {}
    for name, error in errors.items():
        norm = np.linalg.norm(error, axis=-1)
        columns[f"rms_{name}"] = np.sqrt(np.trapezoid(norm**2, t, axis=0) / duration)
        columns[f"iae_{name}"] = np.trapezoid(norm, t, axis=0)
        columns[f"max_{name}"] = norm.max(axis=0)
    return pd.DataFrame(columns).rename_axis("scenario")


class RunningMetrics:
    """Trapezoidal integrals and maxima of the error norms, accumulated period by period.

    Gives the columns of :func:`error_metrics` (RMS, IAE and maximum of the tracking and damping
    errors, from ``t = 0``) without keeping the run, plus the peak position, growth ratio and
    divergence verdict of :class:`~teleopkit.sim.divergence.Divergence`.

    Parameters
    ----------
    state : ndarray, shape (B, 12 n)
        The states at ``t = 0`` (the delayed signals then are the constant past).
    """

    def __init__(self, state: np.ndarray) -> None:
        self.layout = StateLayout.of(state)
        self.t = 0.0
        self.last = self._norms(state, self.layout.get(state, "ql"))
        self.sums = np.zeros((4, state.shape[0]))  # int |e_t|^2, int |e_t|, int |e_d|^2, |e_d|
        self.maxima = self.last.copy()
        self.finite = np.all(np.isfinite(state), axis=1)
        self.magnitude: list[np.ndarray] = []

    def _norms(self, state: np.ndarray, delayed_ql: np.ndarray) -> np.ndarray:
        theta = self.layout.get(state, "theta")
        return np.stack([np.linalg.norm(theta - delayed_ql, axis=-1),
                         np.linalg.norm(theta - self.layout.get(state, "qr"), axis=-1)])

    def add(self, step: Periods) -> None:
        """Accumulate the periods of ``step``.

        Parameters
        ----------
        step : Periods
            The next periods of the run (times, states, delayed signals).
        """
        norms = self._norms(step.state, step.delayed[..., 0, :])  # (2, P, B)
        values = np.concatenate([self.last[:, None], norms], axis=1)
        widths = np.diff(np.concatenate([[self.t], step.t]))[:, None]
        for k, power in enumerate((2, 1, 2, 1)):
            series = values[k // 2] ** power
            self.sums[k] += np.sum(0.5 * (series[1:] + series[:-1]) * widths, axis=0)
        self.maxima = np.fmax(self.maxima, norms.max(axis=1))
        self.finite &= np.all(np.isfinite(step.state), axis=(0, 2))
        self.magnitude.append(position_magnitude(step.state))
        self.t, self.last = float(step.t[-1]), norms[:, -1]

    def frame(self, divergence: Divergence | None = None) -> pd.DataFrame:
        """The metric columns, one row per scenario.

        Parameters
        ----------
        divergence : Divergence, optional
            The criterion; the defaults of :class:`~teleopkit.sim.divergence.Divergence`.

        Returns
        -------
        pandas.DataFrame
            ``rms_track, iae_track, max_track, rms_damp, iae_damp, max_damp`` (``inf`` for a
            run that became non-finite), ``max_position``, ``growth`` and ``diverged``.
        """
        columns = {"rms_track": np.sqrt(self.sums[0] / self.t), "iae_track": self.sums[1],
                   "max_track": self.maxima[0], "rms_damp": np.sqrt(self.sums[2] / self.t),
                   "iae_damp": self.sums[3], "max_damp": self.maxima[1]}
        for name, values in columns.items():
            columns[name] = np.where(self.finite, values, np.inf)
        import pandas as pd

        verdict = (divergence or Divergence()).assess(np.concatenate(self.magnitude),
                                                      self.finite, self.t)
        return pd.DataFrame(columns | verdict)
