"""The certified control loop: every gain is projected by the safety layer, then simulated.

This is the one place where remote gains reach the plant. The environments, the evaluation and
the campaigns step through a :class:`CertifiedLoop`, which also counts applied actions outside
the certified set (``CertifiedLoop.unsafe_actions``, which must stay 0).
"""

from __future__ import annotations

import time

import numpy as np

from teleopkit.delays.profiles import delay_floor
from teleopkit.safety.layer import Projection, SafetyLayer
from teleopkit.sim.energy import BatchRemoteEnergy, motor_speed_integral
from teleopkit.sim.simulator import Simulator
from teleopkit.sim.trajectory import StepResult, Trajectory

__all__ = ["CertifiedLoop"]


class CertifiedLoop:
    """Project raw gains onto the certified set, then simulate one control period with them.

    Parameters
    ----------
    layer : SafetyLayer
        The projection every action passes through.

    Attributes
    ----------
    unsafe_actions : int
        Applied actions outside the certified set since construction (must stay 0).
    unsafe_by_run : ndarray of int, shape (B,)
        The same count per scenario of the current episode.
    seconds : dict of str to float
        Wall time spent since construction in ``"projection"`` (the safety layer, its check and
        its measurements) and in ``"simulation"`` (the simulator's periods): where a step's
        time goes.
    """

    def __init__(self, layer: SafetyLayer) -> None:
        self.layer = layer
        self.seconds = {"projection": 0.0, "simulation": 0.0}
        self.unsafe_actions = 0
        self.unsafe_by_run = np.zeros(0, dtype=np.int64)
        self._simulator: Simulator | None = None
        self._energy: BatchRemoteEnergy | None = None  # the tank's measurement, set at start

    @property
    def simulator(self) -> Simulator:
        """The simulator of the current episode."""
        if self._simulator is None:
            raise RuntimeError("call start() before stepping the loop")
        return self._simulator

    def start(self, simulator: Simulator) -> np.ndarray:
        """Begin an episode on ``simulator`` (reset to ``t = 0``); return its initial states.

        The layer's certificate (when it has one) must be for the simulated plant and for delay
        profiles within its bounds; the layer's run-time state starts afresh.

        Parameters
        ----------
        simulator : Simulator
            The batch of scenarios to run.

        Returns
        -------
        ndarray, shape (B, 12 n)
            The states at ``t = 0``.

        Raises
        ------
        ValueError
            If the certificate is for another plant or smaller delay bounds.
        """
        certificate = self.layer.certificate
        if certificate is not None:
            scenario = simulator.scenario
            certificate.check(scenario.plants, scenario.forward.bound, scenario.backward.bound,
                              (delay_floor(scenario.forward), delay_floor(scenario.backward)))
        simulator.reset()
        self._simulator = simulator
        self._energy = (BatchRemoteEnergy.of(simulator.scenario) if self.layer.measures_energy
                        else None)
        self.unsafe_by_run = np.zeros(simulator.batch, dtype=np.int64)
        self.layer.reset()
        state = simulator.state
        self._measure(state)
        return state

    def _measure(self, state: np.ndarray) -> None:
        """Hand the layer the measurements its tank is paid from (if it keeps one)."""
        if self._energy is not None:
            self.layer.observe(self._energy(state), motor_speed_integral(state))

    def step(self, raw: np.ndarray) -> tuple[StepResult, Projection]:
        """Project ``raw`` and simulate one control period with the applied gains.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n)
            Gains the controller asks for (any values, NaN and inf included).

        Returns
        -------
        result : StepResult
            The period simulated with the applied gains.
        projection : Projection
            What the safety layer did; ``projection.action`` are the applied gains.
        """
        simulator = self.simulator
        started = time.perf_counter()
        raw = np.asarray(raw, dtype=np.float64).reshape(simulator.batch, -1)
        projection = self.layer.step(raw)
        applied = projection.action
        unsafe = ~self.layer.contains(applied)
        self.unsafe_by_run += unsafe
        self.unsafe_actions += int(np.count_nonzero(unsafe))
        projected = time.perf_counter()
        result = simulator.advance(applied)
        simulated = time.perf_counter()
        self._measure(result.state[-1])
        self.seconds["simulation"] += simulated - projected
        self.seconds["projection"] += (projected - started) + (time.perf_counter() - simulated)
        return result, projection

    def run(self, simulator: Simulator, raw: np.ndarray) -> tuple[Trajectory, np.ndarray]:
        """Run a whole episode on a schedule of raw gains.

        Parameters
        ----------
        simulator : Simulator
            The batch of scenarios (reset to ``t = 0``).
        raw : ndarray, shape (P, B, 2 n)
            Raw gains asked for in each control period.

        Returns
        -------
        trajectory : Trajectory
            The run with the applied gains.
        levels : ndarray, shape (P + 1, B)
            The layer's run-time state (budget or tank; NaN without one) just after each
            sample, its jump paid: row ``k`` at ``t_k``, the last row at the end.
        """
        self.start(simulator)
        parts, applied, levels = [simulator.initial_record()], [], []
        for row in raw:
            result, projection = self.step(row)
            parts.append(result)
            applied.append(projection.action)
            levels.append(np.broadcast_to(projection.schedule, (simulator.batch,)))
        final = self.layer.run_time_state(simulator.batch)
        levels.append(final[:, 0] if final.shape[1] else np.full(simulator.batch, np.nan))
        return Trajectory.join(parts, np.stack(applied)), np.stack(levels)
