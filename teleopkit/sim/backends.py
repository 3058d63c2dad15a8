"""The simulator's two integrators behind one interface: the compiled kernel and numpy.

A backend owns the integration state (states and channel histories) of a batch from ``t = 0``;
:class:`~teleopkit.sim.simulator.Simulator` samples the inputs and records the outputs, and
calls :meth:`Backend.advance` with the inputs of the next control periods in the kernel's
factored form (see :func:`teleopkit.sim.kernel.advance`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np

from teleopkit.sim import kernel
from teleopkit.sim.numpy_integrator import NumpyIntegrator
from teleopkit.sim.state import StateLayout

if TYPE_CHECKING:
    from teleopkit.sim.scenarios import Scenario

__all__ = ["Backend", "CompiledBackend", "NumpyBackend", "constant_past"]


def constant_past(state: np.ndarray) -> np.ndarray:
    """What each channel delivers before its first sample, ``(B, 2, n)`` (local, motor).

    Parameters
    ----------
    state : ndarray, shape (B, 12 n)
        States at ``t = 0``.

    Returns
    -------
    ndarray, shape (B, 2, n)
        ``q_l(0)`` and ``theta_r(0)`` of each scenario.
    """
    layout = StateLayout.of(state)
    return np.stack([layout.channel(state, c)[0] for c in (0, 1)], axis=1)


class Backend(Protocol):
    """What the simulator needs of an integrator."""

    @property
    def state(self) -> np.ndarray:
        """Current states ``(B, 12 n)`` (the backend's own array: copy before keeping it)."""

    @property
    def nbytes(self) -> int:
        """Memory of the integration state (states and histories) in bytes."""

    def advance(self, step: int, delays: np.ndarray, scale: np.ndarray, left: np.ndarray,
                unit: np.ndarray, reference_gains: np.ndarray, gains: np.ndarray,
                out_state: np.ndarray, out_delayed: np.ndarray) -> None:
        """Integrate ``gains.shape[0]`` periods from grid step ``step`` into the outputs.

        Parameters
        ----------
        step : int
            Grid index of the current time.
        delays, scale, left : ndarray
            Delays in factored form (:func:`teleopkit.sim.kernel.advance`); ``left`` is empty
            for continuous delays.
        unit, reference_gains : ndarray
            Operator motion ``(S, M, n)`` and each scenario's gains ``(B, n)``.
        gains : ndarray, shape (P, B, 2 n)
            Remote gains held over each period.
        out_state : ndarray, shape (P, B, 12 n)
            Receives the state at the end of each period.
        out_delayed : ndarray, shape (P, B, 2, n)
            Receives the delayed signals at the end of each period.
        """


class CompiledBackend:
    """The numba kernel (:mod:`teleopkit.sim.kernel`) with its ring-buffer histories.

    Parameters
    ----------
    scenario : Scenario
        The batch (its plants and which one each scenario runs).
    state : ndarray, shape (B, 12 n)
        States at ``t = 0``.
    dt : float
        Integration step.
    substeps : int
        Steps per control period.
    bound : float
        Largest delay that will be read.
    """

    def __init__(self, scenario: Scenario, state: np.ndarray, dt: float, substeps: int,
                 bound: float) -> None:
        self.dt, self.substeps = dt, substeps
        self.model = kernel.kernel_model(scenario.plants, scenario.plant_index)
        self._state = np.array(state, dtype=float)
        self.initial = constant_past(self._state)
        n = scenario.params.n_joints
        length = math.ceil(bound / dt) + 2
        # reads before t = 0 take the constant past, so only step 0 (slot 0) needs a value
        self.history = np.zeros((len(state), 2, length, 2 * n))
        self.history[:, :, 0, :n] = self.initial

    @property
    def state(self) -> np.ndarray:
        """Current states ``(B, 12 n)``."""
        return self._state

    @property
    def nbytes(self) -> int:
        """States, constant past and ring buffers, in bytes."""
        return self._state.nbytes + self.history.nbytes + self.initial.nbytes

    def advance(self, step: int, delays: np.ndarray, scale: np.ndarray, left: np.ndarray,
                unit: np.ndarray, reference_gains: np.ndarray, gains: np.ndarray,
                out_state: np.ndarray, out_delayed: np.ndarray) -> None:
        """Integrate with the kernel.

        Parameters
        ----------
        step, delays, scale, left, unit, reference_gains, gains, out_state, out_delayed
            As for :meth:`Backend.advance`.
        """
        kernel.advance(self._state, self.history, self.initial, step, self.dt, self.substeps,
                       delays, scale, left, unit, reference_gains, np.ascontiguousarray(gains),
                       self.model, out_state, out_delayed)


class NumpyBackend:
    """The readable numpy integrator (:mod:`teleopkit.sim.numpy_integrator`).

    Parameters
    ----------
    scenario, state, dt, substeps, bound
        As for :class:`CompiledBackend`.
    """

    def __init__(self, scenario: Scenario, state: np.ndarray, dt: float, substeps: int,
                 bound: float) -> None:
        self.integrator = NumpyIntegrator(scenario, state, dt, substeps, bound)

    @property
    def state(self) -> np.ndarray:
        """Current states ``(B, 12 n)``."""
        return self.integrator.state

    @property
    def nbytes(self) -> int:
        """States and channel histories, in bytes."""
        arrays = [a for channel in self.integrator.channels for a in vars(channel).values()
                  if isinstance(a, np.ndarray)]
        return self.integrator.state.nbytes + sum(a.nbytes for a in arrays)

    def advance(self, step: int, delays: np.ndarray, scale: np.ndarray, left: np.ndarray,
                unit: np.ndarray, reference_gains: np.ndarray, gains: np.ndarray,
                out_state: np.ndarray, out_delayed: np.ndarray) -> None:
        """Integrate in numpy, on the delays and reference multiplied out.

        Parameters
        ----------
        step, delays, scale, left, unit, reference_gains, gains, out_state, out_delayed
            As for :meth:`Backend.advance`.
        """
        out_state[:], out_delayed[:] = self.integrator.advance(
            (delays * scale).transpose(0, 2, 1), reference_gains[None] * unit, gains,
            (left * scale).transpose(0, 2, 1) if left.shape[0] else None)
