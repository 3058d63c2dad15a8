"""Simulator throughput and accuracy, side by side: the compiled kernel, the numpy integrator
backend and jitcdde on the same model.

Run: ``python benchmarks/bench_simulator.py [--quick]``. Prints one table (see
``benchmarks/README.md`` for what each row means and how it is measured).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable

import numpy as np
import pandas as pd

from teleopkit import FourierDelay, Scenario, Simulator, paper_scenarios
from teleopkit.delays.paper_fit import PAPER_C0, PAPER_COS, PAPER_DELAY_MAX, PAPER_F0, PAPER_SIN
from teleopkit.model.dynamics import inertia_coefficients
from teleopkit.model.params import TeleoperatorParams, paper_setup

GAINS = np.array([10.0, 10.0, 30.0, 30.0])
"""Remote gains ``[K_r, K_r, B_r, B_r]`` of every run."""
REFERENCE_GAINS = np.array([[1.0, 1.0]])
"""Operator reference gains ``G`` of the single-scenario runs."""
BATCHES = (1, 64, 1024, 4096)
DTS = (0.0025, 0.00125)
"""Integration steps compared: the default (the largest stable step, within 1e-5 rad) and half
of it."""
ACCURATE_DT = 0.0025
"""The step compared with jitcdde: the default, within 1e-5 rad of the reference."""
FIRST_CALL = "compile (compiled: first call, warm cache), s"
JITCDDE_TOLERANCES = (1e-6, 1e-9)
"""jitcdde ``rtol, atol``: the loosest tried (1e-5/1e-8, 1e-6/1e-9, ...) below 1e-5 rad."""
PERIODS = 25
"""Control periods per ``Simulator.advance`` call in the throughput runs."""
RUN_SECONDS = 4.0
"""Length of the ``Simulator.run`` throughput runs (a 40 s run of 4096 scenarios records 3 GB)."""
EPISODE = 40.0
FINE_DT = 0.000125
"""Step of the accuracy reference (20 times finer than the default; the error falls as dt^5)."""
POSITIONS = [0, 1, 4, 5, 8, 9]
"""Columns of ``q_l``, ``q_r`` and ``theta`` in the 2-link state."""


def best_time(run: Callable[[], object], repeat: int) -> float:
    """Smallest wall time of ``repeat`` calls of ``run`` (after one untimed warm-up call)."""
    run()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


def paper_single() -> Scenario:
    """The paper's scenario with unit delay scales and reference gains (as given to jitcdde)."""
    return Scenario(paper_setup(), FourierDelay(1.0), FourierDelay(1.0), REFERENCE_GAINS)


def throughput(backend: str, batch: int, periods: int, repeat: int, dt: float = 0.0025) -> float:
    """Env-steps (control periods times scenarios) per second through ``Simulator.advance``."""
    sim = Simulator(paper_scenarios(0, batch=batch), dt=dt, backend=backend)
    gains = np.broadcast_to(GAINS, (periods, batch, GAINS.size))
    return periods * batch / best_time(lambda: sim.advance(gains), repeat)


def run_throughput(batch: int, repeat: int, dt: float) -> float:
    """Env-steps per second through ``Simulator.run`` of :data:`RUN_SECONDS` (what a user calls:
    reset, then every period recorded)."""
    sim = Simulator(paper_scenarios(0, batch=batch), dt=dt)
    return round(RUN_SECONDS / sim.control_period) * batch / best_time(
        lambda: sim.run(RUN_SECONDS, GAINS), repeat)


def positions(trajectory_state: np.ndarray) -> np.ndarray:
    """``q_l, q_r, theta`` of scenario 0, shape ``(T, 6)``."""
    return trajectory_state[:, 0, POSITIONS]


def run_compiled(dt: float, duration: float = EPISODE) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of the single paper scenario integrated with step ``dt``."""
    trajectory = Simulator(paper_single(), dt=dt).run(duration, GAINS, chunk=duration)
    return trajectory.t, positions(trajectory.state)


def saturation_margin(params: TeleoperatorParams) -> float:
    """Largest motor torque of the single scenario over the largest allowed (below 1: the
    saturation, which the jitcdde model leaves out, never acts)."""
    trajectory = Simulator(paper_single()).run(EPISODE, GAINS, chunk=EPISODE)
    n = params.n_joints
    state, delayed = trajectory.state[:, 0], trajectory.delayed[:, 0]
    ql, dql, th, dth = state[:, :n], state[:, n:2 * n], state[:, 4 * n:5 * n], state[:, 5 * n:6 * n]
    kl, bl = np.array(params.local_gains.stiffness), np.array(params.local_gains.damping)
    tau_l = kl * (ql - delayed[:, 1]) + bl * dql
    tau_r = -GAINS[:n] * (th - delayed[:, 0]) - GAINS[n:] * dth
    return float(max(np.abs(tau_l).max(), np.abs(tau_r).max()) / params.torque_limit)


class Jitcdde:
    """The 2-link closed loop written for jitcdde: delays ``T_l = T_r = y(t)``, the paper's Fourier
    profile as a symbolic function of time (scale 1), reference gains ``G = (1, 1)``, constant
    gains and past, no torque saturation (see :func:`saturation_margin`)."""

    def __init__(self, params: TeleoperatorParams) -> None:
        import symengine
        from jitcdde import jitcdde, t, y

        self._jitcdde = jitcdde
        n = params.n_joints
        delay = (PAPER_C0 + sum(
            a * symengine.sin(2 * math.pi * k * PAPER_F0 * t)
            + b * symengine.cos(2 * math.pi * k * PAPER_F0 * t)
            for k, (a, b) in enumerate(zip(PAPER_SIN, PAPER_COS, strict=True), start=1))
            ) / PAPER_DELAY_MAX
        op = params.operator
        ql, dql = [y(i) for i in range(n)], [y(n + i) for i in range(n)]
        qr, dqr = [y(2 * n + i) for i in range(n)], [y(3 * n + i) for i in range(n)]
        th, dth = [y(4 * n + i) for i in range(n)], [y(5 * n + i) for i in range(n)]
        local, link, motor = [], [], []
        for i in range(n):
            qh = (REFERENCE_GAINS[0, i] * op.amplitudes[i]
                  * symengine.sin(op.frequencies[i] * t + op.phases[i])
                  * symengine.exp(-op.decays[i] * t))
            tau_l = (params.local_gains.stiffness[i] * (ql[i] - y(4 * n + i, t - delay))
                     + params.local_gains.damping[i] * dql[i])
            tau_r = -GAINS[i] * (th[i] - y(i, t - delay)) - GAINS[n + i] * dth[i]
            tau_h = op.stiffness * (qh - ql[i]) - op.damping * dql[i]
            spring = params.joints.stiffness[i] * (qr[i] - th[i])
            local.append(tau_h - tau_l)
            link.append(-spring)
            motor.append((tau_r + spring) / params.joints.rotor_inertia[i])
        f = [*dql, *self._two_link(params.local_arm, ql, dql, local), *dqr,
             *self._two_link(params.remote_arm, qr, dqr, link), *dth, *motor]
        self.dde = jitcdde(f, max_delay=1.0, verbose=False)
        init = params.initial
        self.initial = np.concatenate([init.local, np.zeros(n), init.remote, np.zeros(n),
                                       init.motor, np.zeros(n)])

    @staticmethod
    def _two_link(arm, q, dq, torque):  # type: ignore[no-untyped-def]
        import symengine

        a = inertia_coefficients(arm)
        c, s = symengine.cos(q[1]), symengine.sin(q[1])
        m12 = a[1, 1] + a[0, 1] * c
        m11 = a[0, 0] + a[0, 1] * c + m12
        h2 = a[0, 1] * s * dq[0] ** 2
        h1 = h2 - a[0, 1] * s * (dq[0] + dq[1]) ** 2
        det = m11 * a[1, 1] - m12**2
        r1, r2 = torque[0] - h1, torque[1] - h2
        return [(a[1, 1] * r1 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det]

    def compile(self) -> float:
        """Generate and compile the C code; return the seconds it took."""
        start = time.perf_counter()
        self.dde.compile_C(simplify=False, do_cse=False, verbose=False)
        return time.perf_counter() - start

    def run(self, times: np.ndarray, rtol: float, atol: float) -> np.ndarray:
        """Positions at ``times`` integrated from the constant past, shape ``(T, 6)``."""
        self.dde.purge_past()
        self.dde.constant_past(self.initial, time=0.0)
        self.dde.set_integration_parameters(rtol=rtol, atol=atol, first_step=1e-3, max_step=0.05)
        self.dde.adjust_diff()  # positions' derivative is already continuous: this changes nothing
        out = [self.initial]
        for target in times[1:]:
            out.append(self.dde.integrate(target))
        return np.array(out)[:, POSITIONS]


def memory_per_scenario(batch: int, periods: int, dt: float) -> int:
    """Bytes per scenario of the compiled backend.

    State, channel history, and the sampled inputs (as far ahead as they are sampled) and
    outputs of one ``advance`` call of ``periods`` periods.
    """
    sim = Simulator(paper_scenarios(0, batch=batch), dt=dt)
    sim._stage_inputs(periods)  # samples the inputs (ahead): times, delays, scales, reference
    sampled = sim._inputs
    arrays = (sampled.times, sampled.delays, sampled.scale, sampled.unit)
    inputs = sum(a.nbytes for a in arrays) // batch + periods * 4 * 8  # and the gains
    outputs = periods * (sim.layout.size + 4 + 2) * 8  # state, delayed signals, delays
    return sim.state_bytes // batch + inputs + outputs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeat = 3 if args.quick else 7
    params = paper_setup()
    columns = {f"compiled {dt * 1e3:g} ms": dt for dt in DTS}
    rows: dict[str, dict[str, float]] = {}

    start = time.perf_counter()
    Simulator(paper_scenarios(0, batch=2)).advance(GAINS)  # compile (or load the cache)
    rows[FIRST_CALL] = {name: time.perf_counter() - start for name in columns}
    for batch in BATCHES:
        rows[f"env-steps/s, batch {batch}"] = {
            name: throughput("compiled", batch, PERIODS, repeat, dt)
            for name, dt in columns.items()}
        rows[f"env-steps/s, batch {batch}"]["numpy 2.5 ms"] = throughput(
            "numpy", batch, 1 if args.quick else 2, 1)
    for batch in BATCHES:
        rows[f"Simulator.run env-steps/s, batch {batch}"] = {
            name: run_throughput(batch, 3, dt) for name, dt in columns.items()}

    t_fine, fine = run_compiled(FINE_DT)
    rows["40 s episode, s"] = {}
    rows["max position error, rad"] = {}
    for name, dt in columns.items():
        rows["40 s episode, s"][name] = best_time(  # the measure, random G and scales
            lambda dt=dt: Simulator(paper_scenarios(0, 1), dt=dt).run(EPISODE, chunk=EPISODE),
            repeat)
        rows["max position error, rad"][name] = float(np.abs(run_compiled(dt)[1] - fine).max())
    rows["max position error, rad"]["numpy 2.5 ms"] = rows["max position error, rad"][
        "compiled 2.5 ms"]  # the backends agree to 1e-10 (tests/sim/test_sim_kernel.py)
    rows["memory per scenario, bytes"] = {name: memory_per_scenario(4096, PERIODS, dt)
                                          for name, dt in columns.items()}

    model = Jitcdde(params)
    rows[FIRST_CALL]["jitcdde"] = model.compile()
    positions_jit = model.run(t_fine, *JITCDDE_TOLERANCES)
    rows["40 s episode, s"]["jitcdde"] = best_time(
        lambda: model.run(t_fine, *JITCDDE_TOLERANCES), 1 if args.quick else 3)
    rows["max position error, rad"]["jitcdde"] = float(np.abs(positions_jit - fine).max())
    jit_rate = (len(t_fine) - 1) / rows["40 s episode, s"]["jitcdde"]
    for batch in BATCHES:  # one scenario at a time: its rate does not grow with the batch
        rows[f"env-steps/s, batch {batch}"]["jitcdde"] = jit_rate
        rows[f"Simulator.run env-steps/s, batch {batch}"]["jitcdde"] = jit_rate

    table = pd.DataFrame(rows).T[[*columns, "numpy 2.5 ms", "jitcdde"]]
    accurate = f"compiled {ACCURATE_DT * 1e3:g} ms"
    speedup = table[accurate] / table["jitcdde"]
    speedup["40 s episode, s"] = 1.0 / speedup["40 s episode, s"]
    table[f"speed-up of {accurate} over jitcdde"] = speedup.where(
        speedup.index.str.startswith(("env-steps", "Simulator.run", "40 s")))
    pd.set_option("display.float_format", lambda v: f"{v:.3g}")
    print(f"paper model, K_r = 10, B_r = 30; {PERIODS} periods per advance call; errors: positions "
          f"over {EPISODE:g} s (G = 1, delay scale 1) against dt = {FINE_DT * 1e3:g} ms; jitcdde "
          f"rtol, atol = {JITCDDE_TOLERANCES}, no saturation (largest torque "
          f"{saturation_margin(params):.2f} of the limit); {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.2f}")
    print(table.to_string())


if __name__ == "__main__":
    main()
