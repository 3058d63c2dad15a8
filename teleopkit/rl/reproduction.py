"""The paper's figures and its comparison table, from the shipped policies (no training).

:func:`reproduce` is what ``teleopkit reproduce`` runs. The table leads with the shipped tuner
whose certificate covers what it does with the gains
(:data:`~teleopkit.rl.policy.PRETRAINED_COVERED`), beside its comparators
(:func:`~teleopkit.rl.comparison.compare`), and keeps the paper's tuner
(:data:`~teleopkit.rl.policy.PRETRAINED`, trained under the frozen-gain certificate, which does
not cover its switching) as the paper's claim: ``covered`` is no on its row. The shipped gain
law (:data:`~teleopkit.rl.policy.PRETRAINED_LAW`), searched on a mix of operators, starts and
delays rather than on this one condition, has its row too (it steps aside for the best
constant gains of its class where they are cheaper on fresh scenarios of the setup).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from teleopkit.progress import reports_progress
from teleopkit.rl.comparison import (
    REFERENCE,
    as_run,
    compare,
    evaluation_config,
    policy_certificate,
    policy_observation,
    report_preamble,
    schedule_label,
    tuner_controller,
    tuner_label,
)
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.evaluation import EVAL_SEED, rollout, save_report
from teleopkit.rl.law_search import stepped_aside
from teleopkit.rl.policy import PRETRAINED, PRETRAINED_COVERED, PRETRAINED_LAW, GainPolicy
from teleopkit.setup import Setup

__all__ = ["PAPER_TUNER", "Reproduction", "reproduce"]

_log = logging.getLogger(__name__)

PAPER_TUNER = "TD3 (paper, frozen)"
"""Row of the paper's tuner: trained under the frozen class, which does not cover it."""


@dataclass(frozen=True)
class Reproduction:
    """What :func:`reproduce` wrote.

    Attributes
    ----------
    summary : pandas.DataFrame
        The comparison table (also ``summary.csv`` and ``summary.md``).
    figures : list of Path
        The paper's figures (PNG).
    out : Path
        The directory.
    """

    summary: pd.DataFrame
    figures: list[Path]
    out: Path


@reports_progress
def reproduce(out: str | Path, scenarios: int = 32, seed: int = EVAL_SEED,
              setup: Setup | None = None, progress: bool | None = None) -> Reproduction:
    """Write the paper's figures and the comparison table of the shipped tuners to ``out``.

    Parameters
    ----------
    out : str or Path
        Directory (created if needed).
    scenarios : int
        Held-out scenarios of the table.
    seed : int
        Their seed.
    setup : Setup, optional
        The scenarios' setup (the paper's by default): another operator, start or network of
        the paper's plant, on which the comparators are searched anew (the shipped tuners are
        certified for the paper's plant only).
    progress : bool, optional
        Show which step runs on standard error: by default on a terminal only; ``False`` never,
        ``True`` always (:mod:`teleopkit.progress`).

    Returns
    -------
    Reproduction
        The table and the figures written.
    """
    from teleopkit.plots import save_paper_figures

    directory = Path(out)
    covered = GainPolicy.pretrained(PRETRAINED_COVERED)
    paper = GainPolicy.pretrained(PRETRAINED)
    certificate = policy_certificate(covered)
    config = evaluation_config(certificate, setup)
    (covered, law), comparators = as_run([covered, GainPolicy.pretrained(PRETRAINED_LAW)],
                                         certificate, config)
    aside = stepped_aside(law)
    law_row = tuner_label(law, certificate.gain_variation)
    per_scenario = compare([covered], scenarios, seed, certificate, comparators=comparators,
                           others={PAPER_TUNER: (paper, replace(config, certificate=None)),
                                   law_row: (tuner_controller(law), replace(
                                       config, observation=policy_observation(law)))},
                           setup=setup)
    tuner = tuner_label(covered, certificate.gain_variation)
    delays = ", ".join(dict.fromkeys(config.setup.network.forward.profiles
                                     + config.setup.network.backward.profiles))
    preamble = report_preamble(comparators, scenarios, seed, delays, tuner, setup=config.setup,
                               others={
        PAPER_TUNER: "the paper's tuner (teleopkit/data/td3_policy.npz), trained under the "
                     "frozen class, whose certificate covers constant gains only: it switches "
                     "them every few steps, so its row is not covered (the paper's claim).",
        law_row: "the shipped gain law (teleopkit/data/law_policy.npz): measured levels of the "
                 "operator's motion and of both errors, the delay and the tank level to the "
                 "gains, searched on a mix of operators, starts and delays (`teleopkit "
                 "search-law --setup mixed`); it adapts across conditions instead of fitting "
                 "this one" + (f"; it {aside}." if aside else ".")})
    preamble += ("\nThis is one condition. The shipped TD3 tuner's win here is the opening of "
                 "the paper's start, damped on a schedule (compare its open-loop row); on other "
                 "starts, operators, walls and delays, each against constant gains searched for "
                 "it, it gains or loses, and the gain law's smaller win here comes with less "
                 "harm elsewhere: `python benchmarks/bench_conditions.py` measures both on "
                 "twenty-three condition families and three mixtures of them, two with plants "
                 "the law never saw (where its feedback beats its own schedule; where constant "
                 "gains are cheaper on fresh scenarios of a setup, such as a random smooth "
                 "operator from rest, the law steps aside for them), and "
                 "`teleopkit evaluate --policy law --setup FILE` on your own setup.\n")
    summary = save_report(per_scenario, directory, baseline=REFERENCE, preamble=preamble,
                          tuner=tuner, schedule=schedule_label(certificate.gain_variation))
    _log.info("reproduction: running the episodes of the figures")
    frozen = replace(config, certificate=None)
    played = replace(config, observation=policy_observation(covered))
    runs = {tuner: rollout(tuner_controller(covered), 1, seed, played).to_frame(),
            PAPER_TUNER: rollout(paper, 1, seed, frozen).to_frame(),
            REFERENCE: rollout(ConstantGains(comparators.frozen_static), 1, seed,
                               frozen).to_frame()}
    _log.info("reproduction: drawing the figures")
    return Reproduction(summary, save_paper_figures(runs, directory), directory)
