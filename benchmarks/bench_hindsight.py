"""What knowing the scenario is worth: gains chosen per scenario with hindsight.

Run from the repository root (about a minute per family on one core; with ``--schedules`` a few
minutes)::

    python benchmarks/bench_hindsight.py [--families NAME ...] [--points 14] [--scenarios 32]
        [--schedules] [--generations 30] [--population 12] [--segments 0 0.5 ...] [--per-joint]
        [--control]

For each condition family of ``bench_conditions.py``: a grid of uniform constant gains (the
same ``K_r`` on every joint, the same ``B_r``; ``points x points`` over the certificate's box,
projected onto the frozen class's certified set) runs on the family's held-out scenarios (seed
7777). The best grid point for the family as a whole is what constant gains can do without
knowing the scenario; the cheapest point of each scenario, chosen after the run, is what they
can do knowing it. Printed: the mean cost of the second against the first (difference of the
mean costs, and mean of the per-scenario ratios). A tuner's feedback within a family can only
beat its own open-loop schedule by telling the family's scenarios apart; where hindsight gains
little, there is little for it to find.

``--schedules`` asks the same of gain *schedules* under the tuners' class (``tank:3``, every
gain projected by its safety layer): piecewise-constant uniform gains over the segments that
start at :data:`SEGMENTS` (short ones first, where the opening transient is), searched by
CMA-ES once for the family as a whole, then again for each scenario alone, started from the
family's schedule (kept where the search finds nothing cheaper). A tuner's run on a scenario is
a schedule for that scenario, so the second is an estimate of the most any feedback could gain
over the family's best schedule in that class (an estimate: the segments restrict it, and the
search may stop short). ``--segments`` sets the segments' start times and ``--per-joint`` lets
every joint's gains move on their own, for a finer and wider search of the same question;
``--control`` continues the family's search as long as each scenario's before comparing, so
that the per-scenario gain is not the family search's unfinished work.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_conditions import families

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import static_cost, uniform_gain_grid
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED, episode_costs
from teleopkit.safety.factory import layer_for
from teleopkit.setup import Setup
from teleopkit.sim.scenarios import Scenario


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


SEGMENTS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
"""Start times in seconds of the schedules' segments (the last runs to the episode's end)."""


class _Schedules:
    """Piecewise-constant gains per lane: lane ``l`` plays ``gains[l, k]`` in segment ``k``."""

    def __init__(self, gains: np.ndarray, segments: tuple[float, ...], period: float) -> None:
        self.gains = gains
        self.starts = np.round(np.array(segments) / period)
        self.step = 0

    def reset(self) -> None:
        self.step = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        segment = int(np.searchsorted(self.starts, self.step, side="right")) - 1
        self.step += 1
        return self.gains[:, segment]


def _schedule_costs(points: np.ndarray, batch: Scenario, config: FlexTeleopConfig,
                    segments: tuple[float, ...] = SEGMENTS, per_joint: bool = False
                    ) -> np.ndarray:
    """Costs ``(C, B)`` of schedules, all in one simulated batch.

    ``points`` in ``[0, 1]^(g S)`` (the gains of each segment over the box: ``K_r`` and ``B_r``,
    ``g = 2``, or with ``per_joint`` every joint's own, ``g = 2 n``): shape ``(C, g S)``, each
    schedule on every scenario, or ``(C, B, g S)``, one per scenario.
    """
    box = config.safety_certificate().box
    n = len(box.lower) // 2
    count, width = len(points), points.shape[-1]
    points = np.broadcast_to(points[:, None] if points.ndim == 2 else points,
                             (count, batch.batch, width))
    x = np.clip(points, 0.0, 1.0).reshape(count * batch.batch, len(segments), -1)
    if per_joint:
        gains = box.lower + x * (box.upper - box.lower)
    else:  # K_r on every joint, then B_r
        low, high = box.lower[[0, n]], box.upper[[0, n]]
        gains = np.repeat(low + x * (high - low), n, axis=-1)
    # lane c B + b: scenario b with schedule (c, b), as Scenario.repeat lays them out
    costs, unsafe = episode_costs(_Schedules(gains, segments, config.control_period),
                                  batch.repeat(count), config)
    if unsafe:
        raise RuntimeError(f"{unsafe} applied gains outside the certified set")
    return costs.reshape(count, batch.batch)


def schedule_hindsight(setup: Setup, scenarios: int, population: int, generations: int,
                       segments: tuple[float, ...] = SEGMENTS, per_joint: bool = False,
                       control: bool = False) -> tuple[float, float]:
    """Per-scenario best schedules against the family's best: mean-cost change, mean ratio.

    With ``control`` the family's search is continued from its best as long as each
    scenario's (the same generations and step size) and the cheaper of the two family schedules
    is the comparator: what the per-scenario searches gain then owes nothing to a family search
    stopped short.
    """
    import cma

    certificate = default_certificate(setup.params, setup.network.reached_bounds,
                                      COVERING_CLASS, setup.plants, setup.ranges)
    config = FlexTeleopConfig(setup, certificate)
    batch = setup.scenarios(np.random.default_rng(EVAL_SEED), scenarios)
    width = len(segments) * (len(certificate.box.lower) if per_joint else 2)

    def costs_of(points: np.ndarray) -> np.ndarray:
        return _schedule_costs(points, batch, config, segments, per_joint)

    options = {"bounds": [0.0, 1.0], "popsize": population, "seed": 1, "verbose": -9}
    family = cma.CMAEvolutionStrategy(np.full(width, 0.3), 0.2, options)
    for _ in range(generations):
        points = np.array(family.ask())
        family.tell(list(points), list(costs_of(points).mean(axis=1)))
    best = np.asarray(family.result.xbest)
    common = costs_of(best[None])[0]
    searches = [cma.CMAEvolutionStrategy(best, 0.1, options) for _ in range(batch.batch)]
    own = common.copy()
    for _ in range(generations):  # every scenario's own search, side by side in one batch
        asked = np.array([search.ask() for search in searches])  # (B, C, width)
        costs = costs_of(asked.transpose(1, 0, 2))
        for b, search in enumerate(searches):
            search.tell(list(asked[b]), list(costs[:, b]))
        own = np.minimum(own, costs.min(axis=0))
    if control:  # the family's search continued as long: what the per-scenario ones owe to it
        family = cma.CMAEvolutionStrategy(best, 0.1, options)
        for _ in range(generations):
            points = np.array(family.ask())
            family.tell(list(points), list(costs_of(points).mean(axis=1)))
        continued = costs_of(np.asarray(family.result.xbest)[None])[0]
        if continued.mean() < common.mean():
            common, own = continued, np.minimum(own, continued)
    return float(own.mean() / common.mean() - 1), float((own / common).mean() - 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--families", nargs="+", default=None, help="family names (default all)")
    parser.add_argument("--points", type=int, default=14, help="grid points per gain")
    parser.add_argument("--scenarios", type=int, default=32)
    parser.add_argument("--schedules", action="store_true",
                        help="schedules under the tuners' class in place of constant gains")
    parser.add_argument("--generations", type=int, default=30, help="CMA-ES generations")
    parser.add_argument("--population", type=int, default=12, help="CMA-ES population")
    parser.add_argument("--segments", nargs="+", type=float, default=list(SEGMENTS),
                        help="start times [s] of the schedules' segments, the first 0")
    parser.add_argument("--per-joint", action="store_true",
                        help="every joint's gains searched on their own (not uniform)")
    parser.add_argument("--control", action="store_true",
                        help="continue the family's search as long as each scenario's first")
    parser.add_argument("--out", type=Path, default=Path("runs/hindsight"),
                        help="where the delay trace of the trace families is written")
    args = parser.parse_args()
    if args.segments[0] != 0 or np.any(np.diff(args.segments) <= 0):
        parser.error("--segments: increasing start times from 0")
    args.out.mkdir(parents=True, exist_ok=True)
    chosen = families(args.out)
    if args.schedules:
        print("| family | hindsight schedules: mean cost | per-scenario ratio |\n|---|---|---|")
    else:
        print("| family | hindsight: mean cost | hindsight: per-scenario ratio | family's best "
              "grid gains |\n|---|---|---|---|")
    for name in args.families or list(chosen):
        if args.schedules:
            change, ratio = schedule_hindsight(chosen[name], args.scenarios, args.population,
                                               args.generations, tuple(args.segments),
                                               args.per_joint, args.control)
            print(f"| {name} | {100 * change:+.1f} % | {100 * ratio:+.1f} % |", flush=True)
            continue
        change, ratio, gains = hindsight(chosen[name], args.points, args.scenarios)
        print(f"| {name} | {100 * change:+.1f} % | {100 * ratio:+.1f} % | "
              f"{' '.join(f'{g:.3g}' for g in gains)} |", flush=True)


if __name__ == "__main__":
    main()
