"""What knowing the scenario is worth: constant gains chosen per scenario with hindsight.

Run from the repository root (about a minute per family on one core)::

    python benchmarks/bench_hindsight.py [--families NAME ...] [--points 14] [--scenarios 32]

For each condition family of ``bench_conditions.py``: a grid of uniform constant gains (the
same ``K_r`` on every joint, the same ``B_r``; ``points x points`` over the certificate's box,
projected onto the frozen class's certified set) runs on the family's held-out scenarios (seed
7777). The best grid point for the family as a whole is what constant gains can do without
knowing the scenario; the cheapest point of each scenario, chosen after the run, is what they
can do knowing it. Printed: the mean cost of the second against the first (difference of the
mean costs, and mean of the per-scenario ratios). A tuner's feedback within a family can only
beat its own open-loop schedule by telling the family's scenarios apart; where hindsight gains
little, there is little for it to find.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_conditions import families

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import static_cost, uniform_gain_grid
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED
from teleopkit.safety.factory import layer_for
from teleopkit.setup import Setup


def hindsight(setup: Setup, points: int, scenarios: int) -> tuple[float, float, np.ndarray]:
    """Per-scenario best grid gains against the family's best: mean-cost change, mean ratio.

    Returns the change of the mean cost and the mean per-scenario ratio minus one (fractions)
    and the family's best grid gains.
    """
    certificate = default_certificate(setup.params, setup.network.reached_bounds, "frozen")
    config = FlexTeleopConfig(setup, certificate)
    layer = layer_for(certificate, config.control_period)
    candidates = uniform_gain_grid(layer, certificate.box.lower, certificate.box.upper, points)
    costs = static_cost(candidates, setup.scenarios(np.random.default_rng(EVAL_SEED), scenarios),
                        config)
    best = int(np.argmin(costs.mean(axis=1)))
    common, own = costs[best], costs.min(axis=0)
    return float(own.mean() / common.mean() - 1), float((own / common).mean() - 1), \
        candidates[best]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--families", nargs="+", default=None, help="family names (default all)")
    parser.add_argument("--points", type=int, default=14, help="grid points per gain")
    parser.add_argument("--scenarios", type=int, default=32)
    parser.add_argument("--out", type=Path, default=Path("runs/hindsight"),
                        help="where the delay trace of the trace families is written")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    chosen = families(args.out)
    print("| family | hindsight: mean cost | hindsight: per-scenario ratio | family's best grid "
          "gains |\n|---|---|---|---|")
    for name in args.families or list(chosen):
        change, ratio, gains = hindsight(chosen[name], args.points, args.scenarios)
        print(f"| {name} | {100 * change:+.1f} % | {100 * ratio:+.1f} % | "
              f"{' '.join(f'{g:.3g}' for g in gains)} |", flush=True)


if __name__ == "__main__":
    main()
