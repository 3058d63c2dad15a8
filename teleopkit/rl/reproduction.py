"""The paper's figures and its comparison table, from the shipped policies (no training).

:func:`reproduce` is what ``teleopkit reproduce`` runs. The table leads with the shipped tuner
whose certificate covers what it does with the gains
(:data:`~teleopkit.rl.policy.PRETRAINED_COVERED`), beside its comparators
(:func:`~teleopkit.rl.comparison.compare`), and keeps the paper's tuner
(:data:`~teleopkit.rl.policy.PRETRAINED`, trained under the frozen-gain certificate, which does
not cover its switching) as the paper's claim: ``covered`` is no on its row.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from teleopkit.rl.comparison import (
    REFERENCE,
    Comparators,
    compare,
    policy_certificate,
    report_preamble,
)
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED, rollout, save_report
from teleopkit.rl.policy import PRETRAINED, PRETRAINED_COVERED, GainPolicy

__all__ = ["PAPER_TUNER", "Reproduction", "reproduce"]

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


def reproduce(out: str | Path, scenarios: int = 32, seed: int = EVAL_SEED) -> Reproduction:
    """Write the paper's figures and the comparison table of the shipped tuners to ``out``.

    Parameters
    ----------
    out : str or Path
        Directory (created if needed).
    scenarios : int
        Held-out scenarios of the table.
    seed : int
        Their seed.

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
    config = FlexTeleopConfig(certificate=certificate)
    comparators = (Comparators.stored(covered, certificate)
                   or Comparators.find(covered, certificate, config))
    per_scenario = compare([covered], scenarios, seed, certificate, comparators=comparators,
                           others={PAPER_TUNER: (paper, FlexTeleopConfig())})
    tuner = f"TD3 ({certificate.gain_variation})"
    preamble = report_preamble(comparators, scenarios, seed, "paper", tuner, others={
        PAPER_TUNER: "the paper's tuner (teleopkit/data/td3_policy.npz), trained under the "
                     "frozen class, whose certificate covers constant gains only: it switches "
                     "them every few steps, so its row is not covered (the paper's claim)."})
    summary = save_report(per_scenario, directory, baseline=REFERENCE, preamble=preamble,
                          tuner=tuner)
    runs = {tuner: rollout(covered, 1, seed, config).to_frame(),
            PAPER_TUNER: rollout(paper, 1, seed).to_frame(),
            REFERENCE: rollout(ConstantGains(comparators.frozen_static), 1, seed).to_frame()}
    return Reproduction(summary, save_paper_figures(runs, directory), directory)
