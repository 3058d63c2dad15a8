"""A tuner against its strongest honest comparators: what ``evaluate`` and ``reproduce`` report.

A trained policy records the certificate it was trained under (:func:`policy_certificate`); it
is evaluated under that certificate unless another one that covers its class is given
(:func:`check_covers`). Beside it, on the same held-out scenarios:

- ``best static``: the best constant gains of the frozen class on the default box, the
  reference of every table (the toughest static comparator: the closed form proves its
  per-joint ratios only for the shape of ``K_l``);
- ``best static (<class>)``: the best constant gains of the tuner's own class;
- ``semi-active (<class>)``: the hand-written semi-active damping law, tuned
  (:func:`~teleopkit.rl.baselines.best_semi_active`), for a class that lets the damping switch;
- ``open-loop (<class>)``: the tuner's mean gain schedule over training scenarios, replayed
  as a function of time alone (is it state feedback, or a schedule?);
- ``fixed``: the paper's gains.

Finding the comparators takes a few minutes of simulation (:meth:`Comparators.find`); they are
stored in the policy's metadata for its certificate (:meth:`Comparators.stored`) and reused
whenever that certificate is the one evaluated.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.verification import load_certificate
from teleopkit.model.params import TeleoperatorParams, paper_setup
from teleopkit.rl.baselines import (
    BASELINE_SEED,
    best_semi_active,
    best_static_gains,
    fixed_gains,
)
from teleopkit.rl.controllers import ConstantGains, GainSchedule, SemiActiveDamping
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED, Controller, evaluate, rollout
from teleopkit.rl.policy import GainPolicy

__all__ = ["REFERENCE", "Comparators", "check_covers", "compare", "policy_certificate",
           "report_preamble"]

REFERENCE = "best static"
"""Name of the reference row: the best static gains of the frozen class."""


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
    expected = _observation_size(certificate)
    size = policy.obs_mean.size
    if size != expected:
        raise ValueError(f"the policy observes {size} values, the certificate's safety layer "
                         f"gives {expected}")


def _observation_size(certificate: GainCertificate) -> int:
    from teleopkit.safety.factory import layer_for

    return 7 * certificate.box.n_joints + layer_for(certificate).run_time_state(1).shape[1]


@dataclass(frozen=True)
class Comparators:
    """The controllers a tuner is compared with, found for one certificate.

    Attributes
    ----------
    certificate : str
        Gain class of the certificate they were found for (with ``fingerprint``, what they
        are reused for).
    fingerprint : str
        The certificate's plant fingerprint and box, as text.
    frozen_static : ndarray, shape (2 n,)
        Best static gains of the frozen class on the default box (the reference).
    class_static : ndarray, shape (2 n,)
        Best static gains of the certificate's set.
    semi_active : tuple of float or None
        ``(K_r, B_low, B_high)`` of the tuned semi-active law (None for the frozen class,
        which does not cover switching damping).
    schedule : ndarray, shape (P, 2 n), or None
        The tuner's mean applied gains per control period on the training scenarios (None for
        the frozen class).
    """

    certificate: str
    fingerprint: str
    frozen_static: np.ndarray
    class_static: np.ndarray
    semi_active: tuple[float, float, float] | None
    schedule: np.ndarray | None

    @staticmethod
    def key(certificate: GainCertificate) -> str:
        """What identifies the certificate the comparators belong to.

        Parameters
        ----------
        certificate : GainCertificate
            A certificate.

        Returns
        -------
        str
            Its plant fingerprint, box, gain class and delay bounds, as JSON text.
        """
        return json.dumps([certificate.plant.get("fingerprint"), certificate.box.to_dict(),
                           certificate.gain_variation, list(certificate.delay_bounds)])

    @classmethod
    def find(cls, policy: GainPolicy, certificate: GainCertificate,
             config: FlexTeleopConfig | None = None) -> Comparators:
        """Search every comparator of ``policy`` under ``certificate`` (a few minutes).

        Parameters
        ----------
        policy : GainPolicy
            The tuner (its mean schedule is replayed open loop).
        certificate : GainCertificate
            The certificate the tuner runs under.
        config : FlexTeleopConfig, optional
            Episode settings (the certificate replaces its own).

        Returns
        -------
        Comparators
            The comparators.
        """
        config = replace(config or FlexTeleopConfig(), certificate=certificate)
        frozen = replace(config, certificate=default_certificate(config.params))
        reference = best_static_gains(config=frozen).gains
        same = cls.key(certificate) == cls.key(frozen.certificate)  # type: ignore[arg-type]
        own = reference if same else best_static_gains(config=config).gains
        semi, schedule = None, None
        if certificate.variation.covers_changes:
            semi_law = best_semi_active(config, start=own).law
            semi = (semi_law.stiffness, semi_law.low, semi_law.high)
            schedule = rollout(policy, 16, BASELINE_SEED, config).applied.mean(axis=1)
        return cls(certificate.gain_variation, cls.key(certificate), reference, own, semi,
                   schedule)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (for the policy's metadata)."""
        return {"certificate": self.certificate, "fingerprint": self.fingerprint,
                "frozen_static": self.frozen_static.tolist(),
                "class_static": self.class_static.tolist(),
                "semi_active": None if self.semi_active is None else list(self.semi_active),
                "schedule": None if self.schedule is None else self.schedule.round(6).tolist()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Comparators:
        """Inverse of :meth:`to_dict`.

        Parameters
        ----------
        data : mapping
            As :meth:`to_dict` writes it.

        Returns
        -------
        Comparators
            The comparators.
        """
        semi = data.get("semi_active")
        schedule = data.get("schedule")
        return cls(str(data["certificate"]), str(data["fingerprint"]),
                   np.asarray(data["frozen_static"], dtype=float),
                   np.asarray(data["class_static"], dtype=float),
                   None if semi is None else tuple(float(x) for x in semi),  # type: ignore
                   None if schedule is None else np.asarray(schedule, dtype=float))

    @classmethod
    def stored(cls, policy: GainPolicy, certificate: GainCertificate) -> Comparators | None:
        """The comparators stored with the policy for this certificate, if any.

        Parameters
        ----------
        policy : GainPolicy
            The tuner.
        certificate : GainCertificate
            The certificate it is evaluated under.

        Returns
        -------
        Comparators or None
            The stored comparators, or None when none were stored for this certificate.
        """
        data = policy.metadata.get("comparators")
        if data is None or data.get("fingerprint") != cls.key(certificate):
            return None
        return cls.from_dict(data)

    def controllers(self, config: FlexTeleopConfig
                    ) -> dict[str, tuple[Controller, FlexTeleopConfig]]:
        """Named controllers with the settings each runs under (reference first).

        Parameters
        ----------
        config : FlexTeleopConfig
            Settings with the tuner's certificate.

        Returns
        -------
        dict
            ``best static`` (frozen class), then the class's best static gains, semi-active
            law and open-loop schedule (where the class covers them), then ``fixed``.
        """
        frozen = replace(config, certificate=default_certificate(config.params))
        rows: dict[str, tuple[Controller, FlexTeleopConfig]] = {
            REFERENCE: (ConstantGains(self.frozen_static), frozen)}
        if self.certificate != "frozen":
            label = f" ({self.certificate})"
            rows["best static" + label] = (ConstantGains(self.class_static), config)
            if self.semi_active is not None:
                rows["semi-active" + label] = (SemiActiveDamping(*self.semi_active), config)
            if self.schedule is not None:
                rows["open-loop" + label] = (GainSchedule(self.schedule), config)
        rows["fixed"] = (ConstantGains(fixed_gains(n_joints=config.params.n_joints)), frozen)
        return rows


def compare(policies: Sequence[GainPolicy], scenarios: int = 32, seed: int = EVAL_SEED,
            certificate: GainCertificate | None = None, delay: str = "paper",
            duration: float = 40.0, comparators: Comparators | None = None,
            others: Mapping[str, tuple[Controller, FlexTeleopConfig]] | None = None,
            params: TeleoperatorParams | None = None) -> pd.DataFrame:
    """Per-scenario metrics of a tuner and its comparators on the same held-out scenarios.

    Parameters
    ----------
    policies : sequence of GainPolicy
        One or more policies of one recipe (training seeds), trained under one class.
    scenarios : int
        Held-out scenarios.
    seed : int
        Their seed.
    certificate : GainCertificate, optional
        The certificate to run the tuner under; default the one its first policy was trained
        under. It must cover that class (:func:`check_covers`).
    delay : str
        Delay profiles of the scenarios (:func:`~teleopkit.rl.evaluation.rollout`).
    duration : float
        Episode length in seconds.
    comparators : Comparators, optional
        Comparators to use; default those stored with the first policy (or found now).
    others : mapping, optional
        More controllers by name, each with its settings (for example a tuner of another
        class).
    params : TeleoperatorParams, optional
        The teleoperator (the paper's by default), for example with another initial state: it
        must be the plant the certificate records.

    Returns
    -------
    pandas.DataFrame
        One row per (controller, policy, scenario), tuner first, then :data:`REFERENCE`, the
        other comparators and ``others``.
    """
    if not policies:
        raise ValueError("compare needs at least one policy")
    certificate = certificate if certificate is not None else policy_certificate(policies[0])
    for policy in policies:
        check_covers(certificate, policy)
    config = FlexTeleopConfig(params=params or paper_setup(), certificate=certificate,
                              episode_length=duration)
    found = (comparators or Comparators.stored(policies[0], certificate)
             or Comparators.find(policies[0], certificate, config))
    rows = {f"TD3 ({certificate.gain_variation})": (list(policies), config),
            **found.controllers(config), **(others or {})}
    controllers = {name: controller for name, (controller, _) in rows.items()}
    settings = {name: setting for name, (_, setting) in rows.items()}
    return evaluate(controllers, scenarios, seed, config, settings, delay)  # type: ignore


def _gains(values: np.ndarray) -> str:
    n = len(values) // 2
    return (f"K_r = ({', '.join(f'{v:.3g}' for v in values[:n])}), "
            f"B_r = ({', '.join(f'{v:.3g}' for v in values[n:])})")


def report_preamble(comparators: Comparators, scenarios: int, seed: int, delay: str,
                    tuner: str, policies: int = 1, duration: float = 40.0,
                    others: Mapping[str, str] | None = None) -> str:
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
        Name of the tuner's row.
    policies : int
        Policies (training seeds) behind the tuner's row.
    duration : float
        Episode length in seconds.
    others : mapping of str to str, optional
        More rows by name, with a sentence each.

    Returns
    -------
    str
        Markdown paragraphs.
    """
    lines = [
        "# Comparison of gain controllers",
        "",
        f"Every row ran the same {scenarios} held-out scenarios (seed {seed}; operator reference "
        f"gains and delay scales no training saw; delays: {delay}), {duration:g} s each, "
        f"every applied gain projected by the safety layer of the row's certificate. `{tuner}` "
        f"is the trained tuner ({policies} polic{'y' if policies == 1 else 'ies'}); "
        f"`{REFERENCE}` the best constant gains of the frozen class on the default box "
        f"({_gains(comparators.frozen_static)}), the reference of the last column; "
        f"`fixed` the paper's gains (K_r = 10, B_r = 30).",
    ]
    if comparators.certificate != "frozen":
        label = comparators.certificate
        lines += ["", f"Of the tuner's class `{label}`: `best static ({label})` its best constant "
                      f"gains ({_gains(comparators.class_static)}); `semi-active ({label})` a "
                      "hand-written law, high damping while the spring deflection grows and low "
                      "while it shrinks at a constant stiffness, its three numbers tuned on "
                      f"training scenarios; `open-loop ({label})` the tuner's mean gain schedule "
                      "over 16 training scenarios, replayed as a function of time alone."]
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
