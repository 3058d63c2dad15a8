"""Time and outcome of the gain-law recipe: ``teleopkit search-law --setup mixed``, per seed.

Run from the repository root (about 15 minutes per seed on 2 cores)::

    python benchmarks/bench_law_search.py [--seeds 0 1 2] [--setup mixed] [--out runs/laws]
        [--references] [--generations 40]

Per seed: the wall time of the start (the best constant gains of the class for the setup,
searched once and reused by the other seeds, as ``teleopkit search-law`` would search them for
each run) and of the search, the generation kept, and its validation against the start gains
(16 fixed scenarios of the setup: mean cost, and the search's objective there: the cost relative
to the start's per scenario, averaged, plus the mean excess where it is dearer). The laws land
in ``--out/seed<k>/best_policy.npz``, for ``benchmarks/bench_conditions.py --policies``.
``--references`` measures every law against each scenario's cheapest of :data:`REFERENCES`
and the start (``LawSearchConfig.references``) instead of against the start alone.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig
from teleopkit.rl.law_search import LawSearchConfig, law_start, search_gain_law
from teleopkit.setup import SHIPPED_SETUPS, Setup, shipped_setup_path

REFERENCES = tuple((k, k, b, b) for k in np.geomspace(1.2, 8.0, 3)
                   for b in np.geomspace(3.0, 22.0, 3))
"""Uniform constant gains on a log grid, ``K_r`` 1.2-8 by ``B_r`` 3-22 (each projected by the
safety layer when it runs): around the best constant gains of the families of
``bench_conditions.py``, from the softest corner's (a small operator from rest) to the
stiffest's."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--setup", default="mixed", help="a shipped setup name or a file")
    parser.add_argument("--out", type=Path, default=Path("runs/laws"))
    parser.add_argument("--references", action="store_true",
                        help="measure the laws against each scenario's cheapest of REFERENCES")
    parser.add_argument("--generations", type=int, default=40)
    args = parser.parse_args()
    path = shipped_setup_path(args.setup) if args.setup in SHIPPED_SETUPS else Path(args.setup)
    setup = Setup.from_file(path)
    certificate = default_certificate(setup.params, setup.network.reached_bounds,
                                      COVERING_CLASS)
    config = FlexTeleopConfig(setup, certificate, observation="adaptive")
    began = time.perf_counter()
    start = law_start(config, progress=False)
    start_time = time.perf_counter() - began
    print(f"start gains {start.round(4).tolist()} in {start_time:.0f} s")
    print("\n| seed | start [s] | search [s] | total [s] | generation kept | validation cost "
          "| start's cost | objective - 1 |")
    print("|---|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        began = time.perf_counter()
        settings = LawSearchConfig(generations=args.generations, seed=seed,
                                   references=REFERENCES if args.references else ())
        result = search_gain_law(start, settings, config,
                                 out_dir=args.out / f"seed{seed}", progress=False)
        search_time = time.perf_counter() - began
        kept = result.log.loc[result.log["validation_objective"].idxmin()]
        print(f"| {seed} | {start_time:.0f} | {search_time:.0f} | {start_time + search_time:.0f} "
              f"| {int(kept['generation'])} | {kept['validation_cost']:.0f} | "
              f"{kept['start_cost']:.0f} | {100 * (kept['validation_objective'] - 1):+.1f} % |",
              flush=True)


if __name__ == "__main__":
    main()
