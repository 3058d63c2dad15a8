"""Tuners across condition families, each against comparators searched for that family.

Run from the repository root (a few minutes per family; comparators are cached)::

    python benchmarks/bench_conditions.py [--policies covered FILE ...] [--families NAME ...]
        [--scenarios 32] [--out runs/conditions] [--no-fall-back]

Every family is a setup (plant, network, operator, start) that differs from the paper's in one
way (one draws each scenario's remote plant from ranges: :data:`PLANT_RANGES`); the last three,
their mixtures, draw the conditions of several families independently per scenario (a user's
varied day: there no constant gains or schedule fits every run, and feedback has something to
find), the second with the plant of each scenario drawn too (the paper's, the heavier softer
arm, the wall), the third with it drawn from :data:`PLANT_RANGES`. For each family and tuner it
runs ``compare``: the tuner, the best constant gains of the frozen class on its certificate's
box (``best static``, the reference), those of the tuner's class, the tuned semi-active law and
the tuner's own mean schedule replayed open loop, all searched for that family on its training
scenarios (never on the held-out ones), on the same held-out scenarios. A gain law runs moved
onto the family's certificate where that set differs from the one it was searched under
(:func:`~teleopkit.rl.law_search.law_under`: constant 0.3 s delays), and steps aside for the
family's best constant gains of its class where they are cheaper on fresh scenarios of the family
(:func:`~teleopkit.rl.law_search.law_or_static`; column ``stepped aside``; ``--no-fall-back``
runs it as searched). It
prints, per family and tuner, the mean cost and the paired differences (per scenario, mean and
standard error) against the family's best static gains of both classes and the tuner's open-loop
schedule (the difference of the mean costs in % of the comparator's, and the mean over the scenarios
of the ratio of costs, which weighs every run the same), with the cost split into the first 2 s and
the rest, and writes ``per_scenario.csv`` and ``summary.csv`` to ``--out``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from teleopkit.certification.certifier import default_certificate
from teleopkit.files import atomic_write
from teleopkit.model.params import PlanarArm, Wall
from teleopkit.rl.comparison import (
    REFERENCE,
    as_run,
    compare,
    evaluation_config,
    policy_certificate,
    schedule_label,
    tuner_label,
)
from teleopkit.rl.evaluation import cost_ratio, paired_difference
from teleopkit.rl.policy import GainPolicy
from teleopkit.setup import MotionSpec, Network, Setup, StartSpec
from teleopkit.setup.network import Channel
from teleopkit.setup.operator import OperatorSetup

PAPER = Setup.paper()
MIXTURE = "mixture of the families"
PLANT_MIXTURE = "mixture with three plants"
RANGE_MIXTURE = "mixture with plants from ranges"
MIXTURES = (MIXTURE, PLANT_MIXTURE, RANGE_MIXTURE)
PLANT_RANGES = {"remote_arm": {"lengths": [0.38, 0.38],
                               "masses": {"min": [0.4, 0.28], "max": [0.75, 0.5]}},
                "joints": {"stiffness": {"min": [60.0, 60.0], "max": [150.0, 150.0]},
                           "rotor_inertia": {"min": [0.2, 0.2], "max": [0.4, 0.4]}}}
"""Remote link masses from 80 % to 150 % of the paper's, joint stiffness from 60 to 150 N m/rad,
rotor inertia from 0.2 to 0.4 kg m^2: a plant drawn per scenario, each value on its own."""


def _motion(kind: str, **settings: object) -> Callable[[Setup], Setup]:
    def change(setup: Setup) -> Setup:
        motion = MotionSpec(kind, tuple(settings.items()))
        operator = OperatorSetup(setup.operator.stiffness, setup.operator.damping, motion)
        return replace(setup, operator=operator, params=replace(
            setup.params, operator=operator.model(setup.n_joints)))
    return change


def _sines(scale: float = 1.0, speed: float = 1.0, decays: tuple[float, float] = (0.05, 0.04),
           ) -> Callable[[Setup], Setup]:
    return _motion("sines", amplitudes=(3.0 * scale, 2.5 * scale),
                   frequencies=(1.0 * speed, 1.6 * speed), phases=(0.0, 0.05), decays=decays,
                   gains=(0.5, 1.0))


def _start(name: str | None = None, spread: float = 0.0) -> Callable[[Setup], Setup]:
    def change(setup: Setup) -> Setup:
        if name is not None:
            start = StartSpec.named(name, 2)
        else:
            start = StartSpec(np.full((3, 2), -spread), np.full((3, 2), spread))
        assert start is not None
        return replace(setup, start=start, params=replace(setup.params,
                                                          initial=start.initial()))
    return change


def _delays(spec: str) -> Callable[[Setup], Setup]:
    return lambda setup: setup.with_delay(spec)


def _remote(masses: float, stiffness: float) -> Callable[[Setup], Setup]:
    """The remote arm's link masses scaled by ``masses``, its joints' stiffness ``stiffness``."""
    def change(setup: Setup) -> Setup:
        arm = setup.params.remote_arm
        scaled = PlanarArm(arm.lengths, tuple(masses * m for m in arm.masses))
        return replace(setup, params=replace(
            setup.params, remote_arm=scaled,
            joints=replace(setup.params.joints, stiffness=(stiffness, stiffness))))
    return change


_plant = _remote(1.5, 60.0)
"""The heavier, softer remote arm: link masses x1.5, joint stiffness 60 N m/rad."""


def _wall(setup: Setup) -> Setup:
    """A stiff wall the remote link's first joint meets at 0.03 rad (it swings about 0.07 rad)."""
    return replace(setup, params=replace(setup.params, environment=Wall((0.03, math.inf))))


def _trace_file(folder: Path) -> Path:
    """A network-like delay trace written to ``folder``: a slow random walk with jitter and rare
    spikes, 0.3-1 s."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 60.0, 0.02)
    walk = np.cumsum(rng.normal(0.0, 0.01, t.size))
    spikes = (rng.random(t.size) < 0.005) * rng.uniform(0.1, 0.3, t.size)
    delay = np.clip(0.6 + walk - walk.mean() + rng.normal(0.0, 0.02, t.size) + spikes, 0.3, 1.0)
    path = (folder / "trace.csv").resolve()
    # atomic: another run on the same folder may be reading it
    atomic_write(path, lambda tmp: pd.DataFrame({"t": t, "delay": delay}).to_csv(tmp, index=False))
    return path


def _trace(folder: Path) -> Callable[[Setup], Setup]:
    """Both channels replay :func:`_trace_file`."""
    def change(setup: Setup) -> Setup:
        channel = Channel(0.0, 1.0, (f"csv:{_trace_file(folder)}",))
        return replace(setup, network=Network(channel, channel))
    return change


def _mixture(folder: Path) -> Setup:
    """The families' conditions drawn independently per scenario: a user's varied day.

    Each scenario draws one operator (the paper's, larger, faster x2, a random smooth motion),
    one start (the paper's, at rest, aligned, random within 0.5 rad) and one delay shape per
    direction (the paper's, switching, constant 0.4 s, the recorded-style trace), all within
    the paper's bound of 1 s. No constant gains or schedule fits all of them.
    """
    sines = {"phases": [0.0, 0.05], "decays": [0.05, 0.04], "gains": [0.5, 1.0]}
    data = PAPER.to_data()
    delays = {"min": 0.0, "max": 1.0, "profile": ["paper", "switching:0:1:50ms",
                                                 "constant:0.4", f"csv:{_trace_file(folder)}"]}
    data["network"] = {"forward": delays, "backward": delays}
    data["operator"]["motion"] = [
        "paper",
        {"sines": {"amplitudes": [4.5, 3.75], "frequencies": [1.0, 1.6], **sines}},
        {"sines": {"amplitudes": [3.0, 2.5], "frequencies": [2.0, 3.2], **sines}},
        {"smooth": {"amplitude": [0.3, 1.5], "frequency": [0.1, 1.0], "decay": [0.0, 0.0],
                    "components": 3}}]
    spread = {"min": [-0.5, -0.5], "max": [0.5, 0.5]}
    data["start"] = ["paper", "rest", "aligned",
                     {"local": spread, "remote": spread, "motor": spread}]
    return Setup.from_data(data)


def _plant_mixture(folder: Path) -> Setup:
    """:func:`_mixture` with each scenario's plant drawn too: the paper's, the heavier softer
    arm of :func:`_plant` and the paper's against the wall of :func:`_wall`."""
    mixture = _mixture(folder)
    return replace(mixture, other_plants=(_plant(PAPER).params, _wall(PAPER).params))


def _ranged(setup: Setup) -> Setup:
    """``setup`` with its remote plant drawn per scenario from :data:`PLANT_RANGES`."""
    data = setup.to_data()
    data["plant"] = {**data["plant"], **PLANT_RANGES}
    return Setup.from_data(data, setup.base)


def families(folder: Path) -> dict[str, Setup]:
    """The condition families, each the paper's setup changed in one way (or two), and their
    mixture."""
    def both(*changes: Callable[[Setup], Setup]) -> Setup:
        setup = PAPER
        for change in changes:
            setup = change(setup)
        return setup

    still = (0.0, 0.0)
    smooth = _motion("smooth", amplitude=(0.3, 1.5), frequency=(0.1, 1.0), decay=(0.0, 0.0),
                     components=3)
    return {
        "paper benchmark": PAPER,
        "operator that does not decay": both(_sines(decays=still)),
        "larger operator amplitudes": both(_sines(scale=1.5)),
        "faster operator x2": both(_sines(speed=2.0)),
        "faster operator x3": both(_sines(speed=3.0)),
        "random smooth operator": both(smooth),
        "start at rest": both(_start("rest")),
        "start without deflection": both(_start("aligned")),
        "random starts": both(_start(spread=0.5)),
        "wall, operator that does not decay": both(_wall, _sines(decays=still)),
        "heavier, softer remote arm": both(_plant),
        "remote plant drawn from ranges": both(_ranged),
        "constant delays 0.3 s": both(_delays("constant:0.3")),
        "switching delays 0-1 s": both(_delays("switching:0:1:50ms")),
        "recorded-style delay trace": both(_trace(folder)),
        # measured later (2026-12-07), after the laws were searched
        "slower operator x0.5": both(_sines(speed=0.5)),
        "smaller operator amplitudes x0.5": both(_sines(scale=0.5)),
        "start at rest, operator that does not decay": both(_start("rest"), _sines(decays=still)),
        "random smooth operator from rest": both(smooth, _start("rest")),
        "random starts 0.3 rad, switching delays": both(_start(spread=0.3),
                                                        _delays("switching:0:1:50ms")),
        "lighter, stiffer remote arm": both(_remote(0.7, 150.0)),
        "sinusoidal delays 0.5+-0.4 s": both(_delays("sine:0.5:0.4:0.2")),
        "constant delays 0.8 s": both(_delays("constant:0.8")),
        MIXTURE: _mixture(folder),
        PLANT_MIXTURE: _plant_mixture(folder),
        RANGE_MIXTURE: _ranged(_mixture(folder)),
    }


def run_family(name: str, setup: Setup, tuners: dict[str, GainPolicy], scenarios: int,
               fall_back: bool = True) -> tuple[pd.DataFrame, list[dict[str, object]]]:
    """Every tuner on one family: per-scenario rows and the summary rows."""
    frames, rows = [], []
    variation = policy_certificate(next(iter(tuners.values()))).gain_variation
    certificate = default_certificate(setup.params, setup.network.reached_bounds, variation,
                                      setup.plants, setup.ranges)
    config = evaluation_config(certificate, setup)
    running, found = as_run(list(tuners.values()), certificate, config, fall_back=fall_back)
    tuners = dict(zip(tuners, running, strict=True))
    for tuner_name, policy in tuners.items():
        comparators = found if policy is running[0] else found.for_policy(policy, config)
        table = compare([policy], scenarios, certificate=certificate, setup=setup,
                        comparators=comparators, progress=False, fall_back=False)  # decided
        label = tuner_label(policy, variation)
        table = table.assign(family=name, tuner=tuner_name)
        frames.append(table)
        mean = table.groupby("controller")[["cost", "cost_opening", "cost_rest"]].mean()
        row: dict[str, object] = {"family": name, "tuner": tuner_name,
                                  "cost": mean.loc[label, "cost"],
                                  "best static": mean.loc[REFERENCE, "cost"]}
        for other, short in ((REFERENCE, "vs static"),
                             (f"best static ({variation})", "vs class static"),
                             (schedule_label(variation), "vs open loop")):
            if other in mean.index:
                relative, _, error = paired_difference(table, label, other)
                ratio = cost_ratio(table, label, other)
                scale = mean.loc[other, "cost"]
                row[short], row[short + " se"] = 100 * relative, 100 * error / scale
                row[short + " per scenario"], row[short + " per scenario se"] = (
                    100 * ratio[0], 100 * ratio[1])
        row["opening saved"] = mean.loc[REFERENCE, "cost_opening"] - mean.loc[label, "cost_opening"]
        row["rest saved"] = mean.loc[REFERENCE, "cost_rest"] - mean.loc[label, "cost_rest"]
        row["static gains"] = " ".join(f"{g:.3g}" for g in comparators.frozen_static)
        row["stepped aside"] = "stepped_aside" in policy.metadata
        rows.append(row)
        print(f"{name:38s} {tuner_name:12s} cost {row['cost']:9.1f}  vs static "
              f"{row['vs static']:+6.1f} % (se {row['vs static se']:.1f})  vs open loop "
              f"{row.get('vs open loop', float('nan')):+6.1f} %"
              f"{'  (stepped aside)' if row['stepped aside'] else ''}", flush=True)
    return pd.concat(frames, ignore_index=True), rows


def _name(policy: str) -> str:
    """A policy's row name: a shipped name as it is, a file by its folder and stem."""
    path = Path(policy)
    return f"{path.parent.name}/{path.stem}" if path.suffix else policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policies", nargs="+", default=["covered"],
                        help="shipped policy names or policy files (the first sets the class)")
    parser.add_argument("--families", nargs="+", default=None, help="family names (default all)")
    parser.add_argument("--scenarios", type=int, default=32)
    parser.add_argument("--out", type=Path, default=Path("runs/conditions"))
    parser.add_argument("--fall-back", action=argparse.BooleanOptionalAction, default=True,
                        help="let a gain law step aside where it does not pay (as_run); "
                             "--no-fall-back runs it as searched")
    args = parser.parse_args()
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    labels = [_name(p) for p in args.policies]
    if len(set(labels)) < len(labels):
        parser.error(f"two policies would share a row name: {labels}")
    tuners = {label: GainPolicy.load(p) for label, p in zip(labels, args.policies, strict=True)}
    chosen = families(args.out)
    names = args.families or list(chosen)
    frames, rows = [], []
    for name in names:
        table, summary = run_family(name, chosen[name], tuners, args.scenarios, args.fall_back)
        frames.append(table)
        rows += summary
    pd.concat(frames).to_csv(args.out / "per_scenario.csv", index=False)
    summary = pd.DataFrame(rows)
    summary.to_csv(args.out / "summary.csv", index=False)
    print(summary.round(2).to_string(index=False))
    for tuner, rows in summary.groupby("tuner", sort=False):
        part = rows[~rows["family"].isin(MIXTURES)]
        if len(part):
            worst = part.loc[part["vs static"].idxmax()]
            print(f"{tuner}: mean of the families vs static {part['vs static'].mean():+.1f} %, "
                  f"worst {worst['vs static']:+.1f} % ({worst['family']}), mean vs open loop "
                  f"{part['vs open loop'].mean():+.1f} %")
        for _, row in rows[rows["family"].isin(MIXTURES)].iterrows():
            print(f"{tuner} on the {row['family']}, per scenario: vs static "
                  f"{row['vs static per scenario']:+.1f} % (se "
                  f"{row['vs static per scenario se']:.1f}), vs open loop "
                  f"{row['vs open loop per scenario']:+.1f} % (se "
                  f"{row['vs open loop per scenario se']:.1f})")


if __name__ == "__main__":
    main()
