"""A tuner against its strongest honest comparators: what ``evaluate`` and ``reproduce`` report.

A trained policy records the certificate it was trained under (:func:`policy_certificate`); it
is evaluated under that certificate unless another one that covers its class is given
(:func:`check_covers`; a gain law is then moved onto that certificate's set,
:func:`~teleopkit.rl.law_search.law_under`). A gain law steps aside for the best constant gains
of its class on a setup where they are cheaper on fresh scenarios of it
(:func:`~teleopkit.rl.law_search.law_or_static`, :func:`as_run`), unless asked to run as
searched. Beside it, on the same held-out scenarios, run its comparators
(:mod:`teleopkit.rl.comparators`: best static gains of the frozen class, the reference of every
table, and of the tuner's class, the tuned semi-active law, the tuner's open-loop schedule, the
paper's fixed gains), searched for the setup being evaluated.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.verification import load_certificate
from teleopkit.progress import reports_progress
from teleopkit.rl.comparators import (
    REFERENCE,
    Comparators,
    comparators_for,
    evaluation_config,
    frozen_counterpart,
    policy_observation,
    schedule_label,
    tuner_controller,
    tuner_label,
)
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED, Controller, evaluate
from teleopkit.rl.features import observation_size
from teleopkit.rl.law_search import law_or_static, law_under
from teleopkit.rl.policy import GainPolicy
from teleopkit.setup import Setup
from teleopkit.sim.timing import DEFAULT_DT

__all__ = ["REFERENCE", "Comparators", "as_run", "check_covers", "comparators_for", "compare",
           "evaluation_config", "frozen_counterpart", "policy_certificate", "policy_observation",
           "report_preamble", "schedule_label", "tuner_controller", "tuner_label", "tuner_rows"]

_log = logging.getLogger(__name__)


def policy_certificate(policy: GainPolicy) -> GainCertificate:
    """The certificate a policy was trained under, re-checked.

    Parameters
    ----------
    policy : GainPolicy
        A policy written by :func:`~teleopkit.rl.training.train` (its metadata holds the
        certificate); a file without one names only its gain class, whose closed-form
        certificate on the default box is returned.

    Returns
    -------
    GainCertificate
        The certificate.

    Raises
    ------
    ValueError
        If the recorded certificate does not re-check.
    """
    recorded = policy.metadata.get("certificate")
    if recorded is None:
        return default_certificate(variation=policy.metadata.get("gain_variation", "frozen"))
    return load_certificate(json.dumps(recorded))


def check_covers(certificate: GainCertificate, policy: GainPolicy) -> None:
    """Refuse a certificate whose class does not cover the class the policy was trained under.

    Parameters
    ----------
    certificate : GainCertificate
        The certificate to evaluate the policy under.
    policy : GainPolicy
        The policy.

    Raises
    ------
    ValueError
        One line naming both classes (or the observation sizes, which a scheduled class's
        run-time state changes).
    """
    trained = policy_certificate(policy).variation
    if not certificate.variation.covers(trained):
        raise ValueError(f"the certificate's class {certificate.gain_variation} does not cover "
                         f"the policy's class {trained} (it was trained under that class)")
    expected = _observation_size(certificate, policy_observation(policy))
    size = policy.obs_mean.size
    if size != expected:
        raise ValueError(f"the policy observes {size} values, the certificate's safety layer "
                         f"gives {expected}")


def _observation_size(certificate: GainCertificate, kind: str) -> int:
    from teleopkit.safety.factory import layer_for

    return (observation_size(kind, certificate.box.n_joints)
            + layer_for(certificate).run_time_state(1).shape[1])


def tuner_rows(policies: Sequence[GainPolicy], variation: str) -> dict[str, list[GainPolicy]]:
    """The tuners' rows of a comparison: the policies grouped by what they are and observe.

    Policies of one kind (TD3 or gain law, :func:`tuner_label`) and one observation
    (:func:`policy_observation`) are training seeds of one tuner: one row. A policy of another
    kind or observation has its own row, run with its own observation. A label that two
    observations share is followed by the observation (``"TD3 (tank:3, adaptive)"``).

    Parameters
    ----------
    policies : sequence of GainPolicy
        The policies, in the order given (the first row is the first policy's).
    variation : str
        The gain class they run under.

    Returns
    -------
    dict of str to list of GainPolicy
        Row name to its policies, in order of first appearance.
    """
    groups: dict[tuple[str, str], list[GainPolicy]] = {}
    for policy in policies:
        key = (tuner_label(policy, variation), policy_observation(policy))
        groups.setdefault(key, []).append(policy)
    labels = [label for label, _ in groups]
    return {(label if labels.count(label) == 1 else f"{label[:-1]}, {observation})"): group
            for (label, observation), group in groups.items()}


@reports_progress
def compare(policies: Sequence[GainPolicy], scenarios: int = 32, seed: int = EVAL_SEED,
            certificate: GainCertificate | None = None, delay: str | None = None,
            duration: float = 40.0, comparators: Comparators | None = None,
            others: Mapping[str, tuple[Controller, FlexTeleopConfig]] | None = None,
            setup: Setup | None = None, progress: bool | None = None,
            dt: float = DEFAULT_DT, fall_back: bool = True) -> pd.DataFrame:
    """Per-scenario metrics of a tuner and its comparators on the same held-out scenarios.

    Parameters
    ----------
    policies : sequence of GainPolicy
        One or more policies, each trained under a class the certificate covers; a gain law
        runs as :func:`as_run` makes it (moved onto the certificate, and with ``fall_back``
        stepping aside where the best constant gains of its class are cheaper on fresh
        scenarios of the setup).
        Policies of one kind and observation (training seeds of one recipe) make one row;
        another kind or observation (a gain law beside a TD3 tuner) makes its own row, run with
        its own observation after the comparators (:func:`tuner_rows`). The comparators are
        the first policy's.
    scenarios : int
        Held-out scenarios.
    seed : int
        Their seed.
    certificate : GainCertificate, optional
        The certificate to run the tuner under; default the one its first policy was trained
        under. It must cover that class (:func:`check_covers`).
    delay : str, optional
        Delays of both directions in place of the setup's network (a delay spec, for example a
        shape the tuner never saw); the comparators are searched with them.
    duration : float
        Episode length in seconds.
    comparators : Comparators, optional
        Comparators to use (their open-loop schedule that of the first policy as it runs
        here, moved onto the certificate if it is a law); default those stored with the first
        policy for this setup and certificate, else found now for them.
    others : mapping, optional
        More controllers by name, each with its settings (for example a tuner of another
        class).
    setup : Setup, optional
        Plant, network, operator motions and starts of the scenarios (the paper's by default):
        its plant must be the one the certificate records.
    progress : bool, optional
        Show which row runs (and the comparators' searches) on standard error: by default on a
        terminal only; ``False`` never, ``True`` always (:mod:`teleopkit.progress`).
    dt : float
        Integration step in seconds (a smaller one for a plant the default cannot integrate).
    fall_back : bool
        Let a gain law step aside where it does not pay (:func:`as_run`); ``False`` runs it
        as searched.

    Returns
    -------
    pandas.DataFrame
        One row per (controller, policy, scenario), tuner first, then :data:`REFERENCE`, the
        other comparators, the other tuners and ``others``.
    """
    if not policies:
        raise ValueError("compare needs at least one policy")
    certificate = certificate if certificate is not None else policy_certificate(policies[0])
    for policy in policies:
        check_covers(certificate, policy)
    config = evaluation_config(certificate, setup, delay, duration, dt)
    policies, found = as_run(policies, certificate, config, comparators, fall_back=fall_back)
    tuners = {name: ([tuner_controller(p) for p in group],
                     replace(config, observation=policy_observation(group[0])))
              for name, group in tuner_rows(policies, certificate.gain_variation).items()}
    first = next(iter(tuners))
    rows = {first: tuners.pop(first), **found.controllers(config), **tuners, **(others or {})}
    controllers = {name: controller for name, (controller, _) in rows.items()}
    settings = {name: setting for name, (_, setting) in rows.items()}
    frames = []
    for row, name in enumerate(controllers, 1):
        _log.info("comparison: row %d of %d, %s on %d scenarios", row, len(controllers), name,
                  scenarios)
        frames.append(evaluate({name: controllers[name]}, scenarios, seed, config,  # type: ignore
                               settings))
    return pd.concat(frames, ignore_index=True)


def as_run(policies: Sequence[GainPolicy], certificate: GainCertificate,
           config: FlexTeleopConfig, comparators: Comparators | None = None,
           on_search: Callable[[], None] | None = None, fall_back: bool = True,
           ) -> tuple[list[GainPolicy], Comparators]:
    """Policies as they run on a setup, and their comparators.

    A gain law is moved onto the certificate (:func:`~teleopkit.rl.law_search.law_under`) and,
    with ``fall_back``, steps aside for the best constant gains of its class where they are
    cheaper on fresh scenarios of the setup (:func:`~teleopkit.rl.law_search.law_or_static`:
    neither those the constant gains were searched on nor held-out ones); any other policy
    runs as it is.

    Parameters
    ----------
    policies : sequence of GainPolicy
        The policies (the first one's open-loop schedule is the comparators').
    certificate : GainCertificate
        The certificate they run under.
    config : FlexTeleopConfig
        Setup and episode settings (:func:`evaluation_config`).
    comparators : Comparators, optional
        Comparators already found for this setup and certificate; by default those stored
        with the first policy, cached or searched now (:func:`comparators_for`).
    on_search : callable, optional
        Called before a search of the comparators, for example to say it takes minutes.
    fall_back : bool
        Let a gain law step aside where it does not pay; ``False`` runs it as searched.

    Returns
    -------
    policies : list of GainPolicy
        The policies as they run.
    comparators : Comparators
        Their comparators, with the open-loop schedule of the first policy as it runs.
    """
    moved = [law_under(policy, config) for policy in policies]
    found = comparators or comparators_for(moved[0], certificate, config, on_search=on_search)
    running = [law_or_static(policy, config, found.class_static) if fall_back else policy
               for policy in moved]
    if running[0] is not moved[0] and found.schedule is not None:
        found = found.for_policy(running[0], replace(config, certificate=certificate))
    return running, found


def _gains(values: np.ndarray) -> str:
    n = len(values) // 2
    return (f"K_r = ({', '.join(f'{v:.3g}' for v in values[:n])}), "
            f"B_r = ({', '.join(f'{v:.3g}' for v in values[n:])})")


def _tuner_words(tuner: str, policies: int) -> str:
    """What the tuner's row is, by its label (:func:`tuner_label`): a searched law or trained."""
    if tuner.startswith("gain law"):
        return (f"the gain law searched by CMA-ES ({policies} "
                f"law{'' if policies == 1 else 's'})")
    return f"the trained tuner ({policies} polic{'y' if policies == 1 else 'ies'})"


def report_preamble(comparators: Comparators, scenarios: int, seed: int, delay: str,
                    tuner: str, policies: int = 1, duration: float = 40.0,
                    others: Mapping[str, str] | None = None, setup: Setup | None = None) -> str:
    """The opening of ``summary.md``: what was compared, and what its words mean.

    Parameters
    ----------
    comparators : Comparators
        The comparators of the table.
    scenarios, seed : int
        Held-out scenarios and their seed.
    delay : str
        Delay profiles of the scenarios.
    tuner : str
        Name of the tuner's row (:func:`tuner_label`): a row named ``"gain law (...)"`` is
        described as a gain law searched by CMA-ES, any other as a trained tuner.
    policies : int
        Policies (training or search seeds) behind the tuner's row.
    duration : float
        Episode length in seconds.
    others : mapping of str to str, optional
        More rows by name, with a sentence each.
    setup : Setup, optional
        The setup the scenarios were drawn from, described in a paragraph.

    Returns
    -------
    str
        Markdown paragraphs.
    """
    lines = [
        "# Comparison of gain controllers",
        "",
        f"Every row ran the same {scenarios} held-out scenarios (seed {seed}, which no "
        "training or search used, draws what the setup leaves random: operator motions, "
        f"delays, starts; delays: {delay}), {duration:g} s each, "
        f"every applied gain projected by the safety layer of the row's certificate. `{tuner}` "
        f"is {_tuner_words(tuner, policies)}; "
        f"`{REFERENCE}` the best constant gains of the frozen class on the certificate's box "
        f"({_gains(comparators.frozen_static)}; searched on training scenarios by a grid, "
        "then Nelder-Mead: a local search, not a proven optimum), the reference of the last "
        "column; "
        f"`fixed` the paper's gains (K_r = 10, B_r = 30).",
    ]
    if comparators.certificate != "frozen":
        label = comparators.certificate
        lines += ["", f"Of the tuner's class `{label}`: `best static ({label})` its best constant "
                      f"gains ({_gains(comparators.class_static)}); `semi-active ({label})` a "
                      "hand-written law, high damping while the spring deflection grows and low "
                      "while it shrinks at a constant stiffness, its three numbers tuned on "
                      f"training scenarios; `{schedule_label(label)}` the tuner's mean gain "
                      "schedule over 16 training scenarios, replayed as a function of time "
                      "alone."]
    if setup is not None:
        lines += ["", "Setup (every comparator was searched for it, on training scenarios "
                      f"drawn from it): {'; '.join(setup.describe())}."]
    for name, text in (others or {}).items():
        lines += ["", f"`{name}`: {text}"]
    lines += [
        "",
        "`cost` is the paper's: the sum over the episode's control periods of "
        "alpha |e_track|^2 + beta |e_damp|^2 + gamma |gains|^2 (minus the return); "
        "`cost_opening` its share in the first 2 s, `cost_rest` the remainder; `rms_track` and "
        "`rms_damp` the RMS tracking error theta_r - q_l(t - T_l) and damping error "
        "theta_r - q_r in rad. `a ± b` is the mean over scenarios ± their standard deviation "
        "(`seeds ± c`: the spread of the per-policy means). `certificate` is the gain class the "
        "row ran under; `covered` says whether that class covers what the controller did with "
        "the gains (the frozen class covers constant gains only: a tuner that switches them "
        "under it is not covered).",
        "",
        "A tuner can be cheaper and track worse: the cost also charges the gains, and a tuner "
        "that keeps its stiffness low saves more on the gain term than it loses on tracking.",
        "",
    ]
    return "\n".join(lines)
