"""Covered tuners against their comparators on delay shapes and scenarios training never saw.

Run from the repository root after ``examples/train_covered.py`` (or with the shipped policy)::

    NUMBA_NUM_THREADS=1 python examples/compare_certified_tuners.py \\
        --policies runs/covered/seed*/best_policy.npz --seeds 7777 2024 --out runs/compare

Every policy runs under the certificate it was trained under (recorded in the file). Beside it,
on the same held-out scenarios (:func:`teleopkit.rl.comparison.compare`): the best static gains
of the frozen class (the reference), the best static gains of the tuner's class, a hand-written
semi-active damping law with its three numbers tuned in closed loop (high damping while the
spring deflection grows, low while it shrinks, at a constant common stiffness: covered with the
storage never rising), the tuner's mean gain schedule replayed open loop, and the paper's fixed
gains. The delay shapes: the paper's profile (as in training), constant 0.6 s, fast switching
between 0 and 1 s every 50 ms, a slow sinusoid between 0.25 and 0.95 s, and a recorded-style
trace with jitter and spikes; the scenario seeds are apart from every training and validation
seed. ``--starts`` adds initial states training never saw (every scenario of training starts
from the paper's ``q_l = (-0.2, 0.2)``, ``q_r = (-0.1, 0.1)``, ``theta = 0``): ``rest`` (all at
zero), ``aligned`` (all at ``q_l(0)``: no spring deflection) and ``deflected`` (twice the
paper's deflection). It prints one table per case (several policies: mean over them, with the
spread over seeds) and writes ``summary.csv`` under ``--out``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from teleopkit.model.params import InitialState, paper_setup
from teleopkit.rl.comparison import REFERENCE, compare, policy_certificate
from teleopkit.rl.evaluation import summarise, to_markdown
from teleopkit.rl.policy import PRETRAINED_COVERED, GainPolicy
from teleopkit.setup import Setup

METRICS = ("cost", "cost_opening", "cost_rest", "rms_track", "rms_damp")

STARTS = {"paper": InitialState(), "rest": InitialState((0.0, 0.0), (0.0, 0.0), (0.0, 0.0)),
          "aligned": InitialState((-0.2, 0.2), (-0.2, 0.2), (-0.2, 0.2)),
          "deflected": InitialState((-0.3, 0.3), (-0.2, 0.2), (0.0, 0.0))}
"""Initial states: the paper's and three that training never saw."""


def recorded_style_trace(path: Path, seed: int = 0, duration: float = 60.0) -> Path:
    """Write a network-like delay trace: a slow random walk with jitter and rare spikes."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 0.02)
    walk = np.cumsum(rng.normal(0.0, 0.01, t.size))
    spikes = (rng.random(t.size) < 0.005) * rng.uniform(0.1, 0.3, t.size)
    delay = np.clip(0.55 + walk - walk.mean() + rng.normal(0.0, 0.02, t.size) + spikes, 0.3, 1.0)
    pd.DataFrame({"t": t, "delay": delay}).to_csv(path, index=False)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policies", nargs="+", type=Path, default=None,
                        help="policy files of one recipe (default: the shipped covered tuner)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[7777, 2024],
                        help="seeds of the held-out scenarios")
    parser.add_argument("--scenarios", type=int, default=32)
    parser.add_argument("--starts", nargs="+", default=["paper"], choices=sorted(STARTS))
    parser.add_argument("--out", type=Path, default=Path("runs/compare"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    policies = ([GainPolicy.load(p) for p in args.policies] if args.policies
                else [GainPolicy.pretrained(PRETRAINED_COVERED)])
    certificate = policy_certificate(policies[0])
    trace = recorded_style_trace(args.out / "recorded_style_trace.csv")
    delays = {"paper": "paper", "constant": "constant:0.6", "switching": "switching:0:1:50ms",
              "sine": "sine:0.6:0.35:0.2", "trace": f"csv:{trace}"}
    tables = []
    cases = [(start, seed, shape) for start in args.starts for seed in args.seeds
             for shape in (delays if start == "paper" else ["paper"])]
    for start, seed, shape in cases:
        # comparators are searched for each start and delay shape (and cached), never reused
        setup = Setup.from_params(replace(paper_setup(), initial=STARTS[start]))
        summary = summarise(compare(policies, args.scenarios, seed, certificate,
                                    None if shape == "paper" else delays[shape], setup=setup))
        tables.append(summary.assign(delay=shape, scenario_seed=seed, start=start))
        print(f"\nstart: {start}, delays: {shape}, scenario seed {seed}", flush=True)
        print(to_markdown(summary, METRICS, baseline=REFERENCE), flush=True)
    pd.concat(tables).to_csv(args.out / "summary.csv")


if __name__ == "__main__":
    main()
