"""The environment's step, whole and by part, against Gymnasium's Pendulum as a yardstick.

One step of ``teleopkit/FlexTeleop-v0`` observes the state, projects the raw gains onto the
certified set, simulates one 10 ms control period and scores it. The table times the whole step
for one scenario (``gymnasium.make``, with its wrappers) and per scenario of a batch
(``FlexTeleopVectorEnv``), the projection and the simulated period alone, a period of the same
model integrated by jitcdde (``bench_simulator.py``'s model), and the step of
``Pendulum-v1``, whose dynamics are one line of numpy: what a step costs when the simulation is
free.

Run: ``NUMBA_NUM_THREADS=1 python benchmarks/bench_env.py [--steps N]``.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import gymnasium
import numpy as np
import pandas as pd

import teleopkit.rl  # noqa: F401  (registers the environment)
from teleopkit.model.params import paper_setup
from teleopkit.rl.env import FlexTeleopVectorEnv
from teleopkit.rl.registration import ENV_ID
from teleopkit.sim import Simulator, paper_scenarios
from teleopkit.sim.timing import CONTROL_PERIOD

ACTION = np.array([10.0, 10.0, 30.0, 30.0])
"""Remote gains ``[K_r, K_r, B_r, B_r]`` of every step (inside the default certified set)."""
BATCH = 1024


def per_call(call: Callable[[], object], count: int, repeats: int = 3) -> float:
    """Best mean seconds per call of ``count`` calls, over ``repeats`` rounds."""
    call()
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(count):
            call()
        best = min(best, (time.perf_counter() - start) / count)
    return best


def stepper(env: gymnasium.Env | FlexTeleopVectorEnv, action: np.ndarray) -> Callable[[], None]:
    """One step of ``env`` with ``action``, resetting at the end of an episode."""
    env.reset(seed=0)

    def step() -> None:
        *_, terminated, truncated, _ = env.step(action)
        if isinstance(terminated, np.ndarray):  # a vector env: one flag per scenario
            terminated, truncated = terminated.any(), truncated.any()
        if terminated or truncated:  # a single env's flags are bools (np.any costs 2 µs)
            env.reset()

    return step


def jitcdde_period() -> float:
    """Seconds per control period of jitcdde integrating the same closed loop period by period
    (``bench_simulator.Jitcdde``: a 40 s run at its matching accuracy, one ``integrate`` call per
    10 ms, best of 3), as the environment would call it."""
    from bench_simulator import EPISODE, JITCDDE_TOLERANCES, Jitcdde

    model = Jitcdde(paper_setup())
    model.compile()
    times = np.linspace(0.0, EPISODE, round(EPISODE / CONTROL_PERIOD) + 1)
    return per_call(lambda: model.run(times, *JITCDDE_TOLERANCES), 1) / (times.size - 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per timing round")
    args = parser.parse_args()
    rows: dict[str, float] = {}

    single = gymnasium.make(ENV_ID)
    rows["FlexTeleop-v0, one scenario (gymnasium.make)"] = per_call(
        stepper(single, ACTION), args.steps)
    layer, previous = single.unwrapped.safety_layer, ACTION[None]
    rows["  projection alone"] = per_call(lambda: layer.project_batch(ACTION[None], previous),
                                          args.steps)
    simulator = Simulator(paper_scenarios(0, batch=1))  # the env's plant, delays and step
    rows["  one simulated period alone"] = per_call(lambda: simulator.advance(ACTION[None]),
                                                    args.steps)
    rows["  jitcdde: one period of the same model"] = jitcdde_period()
    vector = FlexTeleopVectorEnv(BATCH)
    batch_actions = np.tile(ACTION, (BATCH, 1))
    rows[f"FlexTeleopVectorEnv, per scenario of {BATCH}"] = per_call(
        stepper(vector, batch_actions), max(1, args.steps // 100)) / BATCH
    pendulum = gymnasium.make("Pendulum-v1")
    rows["Pendulum-v1 (gymnasium.make)"] = per_call(
        stepper(pendulum, np.zeros(1, dtype=np.float32)), args.steps)

    table = pd.DataFrame({"µs per env-step": {k: v * 1e6 for k, v in rows.items()}})
    table["env-steps/s"] = 1e6 / table["µs per env-step"]
    table["vs Pendulum"] = table["µs per env-step"] / rows["Pendulum-v1 (gymnasium.make)"] / 1e6
    pd.set_option("display.float_format", lambda v: f"{v:.3g}")
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}, "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'all')}")
    print(table.to_string())


if __name__ == "__main__":
    main()
