"""What a simulation returns: the states of control periods, and a whole recorded run.

:class:`StepResult` is the outcome of :meth:`~teleopkit.sim.simulator.Simulator.advance`;
:class:`Trajectory` is a run from ``t = 0`` (:meth:`~teleopkit.sim.simulator.Simulator.run`)
with the gains in force, the tracking and damping errors, their metrics and a table of one
scenario. States follow :class:`~teleopkit.sim.state.StateLayout`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from teleopkit.sim.divergence import Divergence
from teleopkit.sim.metrics import error_metrics
from teleopkit.sim.state import Field, StateLayout

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["StepResult", "Trajectory"]


@dataclass(frozen=True)
class StepResult:
    """Outcome of :meth:`~teleopkit.sim.simulator.Simulator.advance` over ``P`` control periods.

    Attributes
    ----------
    t : ndarray, shape (P,)
        End time of each period.
    state : ndarray, shape (P, B, 12 n)
        States (:class:`~teleopkit.sim.state.StateLayout`) at each time.
    delayed : ndarray, shape (P, B, 2, n)
        ``q_l(t - T_l)`` and ``theta(t - T_r)``.
    delays : ndarray, shape (P, B, 2)
        ``T_l(t)`` and ``T_r(t)``.
    """

    t: np.ndarray
    state: np.ndarray
    delayed: np.ndarray
    delays: np.ndarray

    def rows(self, index: slice) -> StepResult:
        """The times ``index`` of this record, as views.

        Parameters
        ----------
        index : slice
            Rows to keep.

        Returns
        -------
        StepResult
            Views of ``t``, ``state``, ``delayed`` and ``delays`` (writing to them writes here).
        """
        return StepResult(self.t[index], self.state[index], self.delayed[index],
                          self.delays[index])

    @property
    def layout(self) -> StateLayout:
        """The layout of ``state``."""
        return StateLayout.of(self.state)

    @property
    def e_track(self) -> np.ndarray:
        """Tracking error ``theta_r - q_l(t - T_l)``, shape ``(P, B, n)``."""
        return self.layout.get(self.state, "theta") - self.delayed[..., 0, :]

    @property
    def e_damp(self) -> np.ndarray:
        """Damping (flexibility) error ``theta_r - q_r``, shape ``(P, B, n)``."""
        return self.layout.get(self.state, "theta") - self.layout.get(self.state, "qr")


@dataclass(frozen=True)
class Trajectory(StepResult):
    """A recorded run: a :class:`StepResult` from ``t = 0`` including the initial row.

    ``P`` is the number of recorded times: the control periods of the run plus the row at
    ``t = 0``.

    Attributes
    ----------
    t : ndarray, shape (P,)
        Recorded times in seconds: ``0`` then the end time of each period.
    state : ndarray, shape (P, B, 12 n)
        States at each time (row 0 is the initial state).
    delayed : ndarray, shape (P, B, 2, n)
        ``q_l(t - T_l)`` and ``theta(t - T_r)`` (row 0 holds the constant past, the initial
        ``q_l`` and ``theta``).
    delays : ndarray, shape (P, B, 2)
        ``T_l(t)`` and ``T_r(t)`` in seconds.
    gains : ndarray, shape (P, B, 2 n)
        Remote gains in force at each time (row 0 holds the first period's gains); a read-only
        broadcast view when they were constant.
    """

    gains: np.ndarray

    @classmethod
    def join(cls, parts: list[StepResult], gains: np.ndarray) -> Trajectory:
        """Concatenate the initial row and the periods that followed it.

        Parameters
        ----------
        parts : list of StepResult
            The record at ``t = 0``, then the results of successive advances.
        gains : ndarray, shape (P - 1, B, 2 n)
            The gains applied over each period.

        Returns
        -------
        Trajectory
            The run.
        """
        def joined(name: str) -> np.ndarray:
            return np.concatenate([getattr(part, name) for part in parts])

        return cls(t=joined("t"), state=joined("state"), delayed=joined("delayed"),
                   delays=joined("delays"), gains=np.concatenate([gains[:1], gains]))

    def metrics(self) -> pd.DataFrame:
        """RMS, IAE and maximum of the tracking and damping errors, one row per scenario."""
        return error_metrics(self.t, {"track": self.e_track, "damp": self.e_damp})

    def diverged_at(self, divergence: Divergence | None = None) -> np.ndarray:
        """When each scenario diverged (:meth:`~teleopkit.sim.divergence.Divergence.onset`).

        Parameters
        ----------
        divergence : Divergence, optional
            The criterion; the defaults of :class:`~teleopkit.sim.divergence.Divergence`.

        Returns
        -------
        ndarray, shape (B,)
            The first time in seconds its state stopped being finite or a position left the
            divergence radius; NaN for a scenario that did neither.
        """
        return (divergence or Divergence()).onset(self.t, self.state)

    def columns(self, scenario: int = 0) -> dict[str, np.ndarray]:
        """One scenario as named columns ``t, ql_i, qr_i, theta_i, ..., Kr_i, Br_i``.

        Parameters
        ----------
        scenario : int
            Index of the scenario in the batch, from 0.

        Returns
        -------
        dict of str to ndarray, shape (P,)
            ``t, ql_i, dql_i, qr_i, dqr_i, theta_i, dtheta_i, Tl, Tr, ql_delayed_i,
            theta_delayed_i, e_track_i, e_damp_i, Kr_i, Br_i`` (``i`` the joint, from 1).
        """
        layout = self.layout
        n = layout.n_joints
        state = self.state[:, scenario]
        names: tuple[Field, ...] = ("ql", "dql", "qr", "dqr", "theta", "dtheta")
        signals: dict[str, np.ndarray] = {name: layout.get(state, name) for name in names}
        columns: dict[str, np.ndarray] = {"t": self.t}
        for name, signal in signals.items():
            columns.update({f"{name}_{i + 1}": signal[:, i] for i in range(n)})
        columns["Tl"] = self.delays[:, scenario, 0]
        columns["Tr"] = self.delays[:, scenario, 1]
        for name, signal in (("ql_delayed", self.delayed[:, scenario, 0]),
                             ("theta_delayed", self.delayed[:, scenario, 1]),
                             ("e_track", self.e_track[:, scenario]),
                             ("e_damp", self.e_damp[:, scenario]),
                             ("Kr", self.gains[:, scenario, :n]),
                             ("Br", self.gains[:, scenario, n:])):
            columns.update({f"{name}_{i + 1}": signal[:, i] for i in range(n)})
        return columns

    def to_frame(self, scenario: int = 0) -> pd.DataFrame:
        """One scenario as a table: the columns of :meth:`columns`, one row per recorded time.

        Parameters
        ----------
        scenario : int
            Index of the scenario in the batch, from 0.

        Returns
        -------
        pandas.DataFrame
            The table.
        """
        import pandas as pd

        return pd.DataFrame(self.columns(scenario))
