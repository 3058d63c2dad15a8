"""Wall-clock time for the covered recipe to come 10 % below the frozen class's best static gains.

    NUMBA_NUM_THREADS=2 python benchmarks/bench_covered_recipe.py [--recipe paper|fast]
        [--seeds 0 1 2] [--rounds 12]

Trains a recipe of ``teleopkit train`` (``teleopkit.rl.recipes.RECIPES``, the paper's by
default, under its covering class ``teleopkit.rl.env.COVERING_CLASS``) seed by seed, alone on the
machine, and stops a seed at
the first round whose validation cost (the deterministic actor under the covering certificate,
16 validation scenarios) is at least 10 % below that of the best static gains of the frozen class
on the same scenarios. Prints, per seed, that round and the training's wall-clock time to it
(rollouts, updates and validations; the static gains' own search is excluded and printed apart).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd
import torch

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import best_static_gains
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig
from teleopkit.rl.evaluation import rollout
from teleopkit.rl.recipes import RECIPES
from teleopkit.rl.training import train


class _Reached(Exception):
    """Raised from the round callback to stop a seed at its first round below the target."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--rounds", type=int, default=12, help="most rounds per seed")
    parser.add_argument("--recipe", choices=list(RECIPES), default="paper")
    args = parser.parse_args()
    torch.set_num_threads(1)
    recipe = RECIPES[args.recipe]
    start = time.perf_counter()
    static = best_static_gains().gains
    frozen = rollout(ConstantGains(static), recipe.validation_scenarios, recipe.validation_seed,
                     FlexTeleopConfig())
    target = 0.9 * float(-frozen.reward.sum(axis=0).mean())
    print(f"frozen best static gains {static.round(3).tolist()}: validation cost "
          f"{target / 0.9:.0f}, target {target:.0f} (found in {time.perf_counter() - start:.0f} "
          "s, not counted)")
    config = FlexTeleopConfig(certificate=default_certificate(variation=COVERING_CLASS))
    print("\n| seed | round | validation cost | wall-clock time to it [s] |\n|---|---|---|---|")
    for seed in args.seeds:
        rounds = recipe.num_envs * replace(config, episode_length=recipe.episode_length).max_steps
        settings = replace(recipe, total_steps=args.rounds * rounds, seed=seed)
        with tempfile.TemporaryDirectory() as out:
            log: list[float] = []

            def check(done: int, out: str = out, log: list[float] = log) -> None:
                row = pd.read_csv(Path(out) / "train_log.csv").iloc[-1]
                log[:] = [done, row["validation_cost"], row["wall_time"]]
                if row["validation_cost"] <= target:
                    raise _Reached

            try:
                train(settings, out, env_config=config, progress=False, on_round=check)
                reached = False
            except _Reached:
                reached = True
        done, cost, wall = log
        mark = "" if reached else f" (not reached in {args.rounds} rounds)"
        print(f"| {seed} | {int(done)} | {cost:.0f}{mark} | {wall:.0f} |", flush=True)


if __name__ == "__main__":
    main()
