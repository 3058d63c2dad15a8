"""The comparators of a tuner, searched for the question it is evaluated on.

- ``best static``: the best constant gains of the frozen class on the tuner certificate's box
  and delay bounds, the reference of every table (the toughest static comparator: the closed
  form proves its per-joint ratios only for the shape of ``K_l``);
- ``best static (<class>)``: the best constant gains of the tuner's own class;
- ``semi-active (<class>)``: the hand-written semi-active damping law, tuned
  (:func:`~teleopkit.rl.baselines.best_semi_active`), for a class that lets the damping switch;
- ``open-loop (<class>)``: the tuner's mean gain schedule over training scenarios, replayed
  as a function of time alone (is it state feedback, or a schedule?);
- ``fixed``: the paper's gains.

Every comparator is searched for the setup being evaluated (plant, network, operator motions,
starts: :class:`~teleopkit.setup.Setup`) on its training scenarios, never reused from another
setup. Finding them takes a few minutes of simulation (:meth:`Comparators.find`); they are
stored in the policy's metadata under their key, the setup's fingerprint and the certificate
(:meth:`Comparators.stored`), and reused only for that setup and certificate; the tuner-free
ones are cached on disk (:func:`comparators_for`).
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable, Mapping
from dataclasses import astuple, dataclass, replace
from typing import Any

import numpy as np

from teleopkit.certification.certifier import certify_gains
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.verification import cover_plants
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.records import plant_params
from teleopkit.rl.baselines import (
    BASELINE_SEED,
    best_semi_active,
    best_static_gains,
    fixed_gains,
)
from teleopkit.rl.controllers import (
    ConstantGains,
    GainSchedule,
    HeldController,
    SemiActiveDamping,
)
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import Controller, rollout
from teleopkit.rl.policy import GainPolicy
from teleopkit.setup import Setup
from teleopkit.sim.timing import DEFAULT_DT

__all__ = ["REFERENCE", "Comparators", "comparators_for", "evaluation_config",
           "frozen_counterpart", "policy_observation", "schedule_label", "tuner_controller",
           "tuner_label"]

_log = logging.getLogger(__name__)

REFERENCE = "best static"
"""Name of the reference row: the best static gains of the frozen class."""


def schedule_label(variation: str) -> str:
    """Name of the row of a tuner's own open-loop mean schedule under a class.

    Parameters
    ----------
    variation : str
        The tuner's gain-variation class (``"tank:3"``, ...).

    Returns
    -------
    str
        ``"open-loop (<class>)"``.
    """
    return f"open-loop ({variation})"


def frozen_counterpart(certificate: GainCertificate, params: TeleoperatorParams
                       ) -> GainCertificate:
    """The frozen class's closed-form certificate of the same box and delay bounds.

    The reference row's set: constant gains the closed form certifies inside the tuner's box.

    Parameters
    ----------
    certificate : GainCertificate
        The tuner's certificate.
    params : TeleoperatorParams
        Its plant.

    Returns
    -------
    GainCertificate
        ``certificate`` itself if it is a closed-form certificate of the frozen class; else the
        frozen one, covering the same further plants and ranges.
    """
    if certificate.gain_variation == "frozen" and certificate.method == "nuno":
        return certificate
    frozen = certify_gains(params, certificate.box, *certificate.delay_bounds, method="nuno",
                           variation="frozen")
    return cover_plants(frozen, [plant_params(record) for record in
                                 (certificate.plant, *certificate.other_plants)],
                        certificate.ranges)


def policy_observation(policy: GainPolicy) -> str:
    """What the policy observes: ``"paper"`` or ``"adaptive"`` (recorded when it was trained).

    Parameters
    ----------
    policy : GainPolicy
        A policy.

    Returns
    -------
    str
        The observation kind of :class:`~teleopkit.rl.env.FlexTeleopConfig`.
    """
    return str(policy.metadata.get("observation", "paper"))


def tuner_label(policy: GainPolicy, variation: str) -> str:
    """The row name of a tuner in a comparison: what it is and its gain class.

    Parameters
    ----------
    policy : GainPolicy
        The tuner (its metadata says how it was made).
    variation : str
        The gain class it runs under.

    Returns
    -------
    str
        ``"gain law (CLASS)"`` for a law searched by :mod:`teleopkit.rl.law_search`, else
        ``"TD3 (CLASS)"``.
    """
    kind = "gain law" if "law_search" in policy.metadata else "TD3"
    return f"{kind} ({variation})"


def tuner_controller(policy: GainPolicy) -> Controller:
    """The policy as it plays in evaluation: held over its decision period when it has one.

    Parameters
    ----------
    policy : GainPolicy
        A policy (its metadata's ``decision_period``, 1 when absent).

    Returns
    -------
    Controller
        The policy, or a :class:`~teleopkit.rl.controllers.HeldController` of it.
    """
    periods = int(policy.metadata.get("decision_period", 1))
    return policy if periods == 1 else HeldController(policy, periods)


@dataclass(frozen=True)
class Comparators:
    """The controllers a tuner is compared with, found for one certificate.

    Attributes
    ----------
    certificate : str
        Gain class of the certificate they were found for (with ``fingerprint``, what they
        are reused for).
    fingerprint : str
        :meth:`key`: the setup's fingerprint, the certificate's plant fingerprint, box, class
        and delay bounds, the episode length and the reward weights, as text.
    frozen_static : ndarray, shape (2 n,)
        Best static gains of the frozen class on the certificate's box (the reference).
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
    def key(certificate: GainCertificate, config: FlexTeleopConfig) -> str:
        """What identifies the question the comparators answer.

        Parameters
        ----------
        certificate : GainCertificate
            The certificate the tuner runs under.
        config : FlexTeleopConfig
            The setup and episode settings they were searched for.

        Returns
        -------
        str
            The setup's fingerprint, the certificate's plant fingerprint, box, gain class and
            delay bounds, the episode length and the reward weights, and the integration step
            where it is not the default, as JSON text.
        """
        step = [] if config.dt == DEFAULT_DT else [config.dt]
        return json.dumps([config.setup.fingerprint, certificate.plant.get("fingerprint"),
                           certificate.box.to_dict(), certificate.gain_variation,
                           list(certificate.delay_bounds), config.episode_length,
                           list(astuple(config.weights)), *step])

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
        static = cls.find_static(certificate, config)
        return static.for_policy(policy, config) if static.semi_active is not None else static

    @classmethod
    def find_static(cls, certificate: GainCertificate, config: FlexTeleopConfig
                    ) -> Comparators:
        """Search the comparators that do not depend on the tuner (no open-loop schedule).

        Parameters
        ----------
        certificate : GainCertificate
            The certificate the tuner runs under.
        config : FlexTeleopConfig
            Setup and episode settings (the certificate replaces its own).

        Returns
        -------
        Comparators
            Best static gains of both classes and, for a class that lets the damping switch,
            the semi-active law; ``schedule`` is None (:meth:`for_policy` adds it).
        """
        config = replace(config, certificate=certificate)
        frozen = replace(config, certificate=frozen_counterpart(certificate, config.params))
        reference = best_static_gains(config=frozen).gains
        same = frozen.certificate is certificate
        own = reference if same else best_static_gains(config=config).gains
        semi = None
        if certificate.variation.covers_changes:
            semi_law = best_semi_active(config, start=own).law
            semi = (semi_law.stiffness, semi_law.low, semi_law.high)
        return cls(certificate.gain_variation, cls.key(certificate, config), reference, own,
                   semi, None)

    def for_policy(self, policy: GainPolicy, config: FlexTeleopConfig) -> Comparators:
        """These comparators with the open-loop schedule of another tuner of the same class.

        The static gains and the semi-active law depend on the question only; the schedule is
        the tuner's mean applied gains per control period on 16 training scenarios.

        Parameters
        ----------
        policy : GainPolicy
            The tuner.
        config : FlexTeleopConfig
            The settings the comparators were found for (with the tuner's certificate).

        Returns
        -------
        Comparators
            A copy with the tuner's schedule.
        """
        _log.info("open-loop schedule: running the tuner on 16 training scenarios")
        observed = replace(config, observation=policy_observation(policy))
        schedule = rollout(tuner_controller(policy), 16, BASELINE_SEED,
                           observed).applied.mean(axis=1)
        return replace(self, schedule=schedule)

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
    def stored(cls, policy: GainPolicy, certificate: GainCertificate,
               config: FlexTeleopConfig) -> Comparators | None:
        """The comparators stored with the policy for this certificate and setup, if any.

        Parameters
        ----------
        policy : GainPolicy
            The tuner.
        certificate : GainCertificate
            The certificate it is evaluated under.
        config : FlexTeleopConfig
            The setup and episode settings it is evaluated on.

        Returns
        -------
        Comparators or None
            The stored comparators, or None when none were stored for this question.
        """
        data = policy.metadata.get("comparators")
        if data is None or data.get("fingerprint") != cls.key(certificate, config):
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
        frozen = replace(config, certificate=frozen_counterpart(config.safety_certificate(),
                                                                config.params))
        rows: dict[str, tuple[Controller, FlexTeleopConfig]] = {
            REFERENCE: (ConstantGains(self.frozen_static), frozen)}
        if self.certificate != "frozen":
            label = f" ({self.certificate})"
            rows["best static" + label] = (ConstantGains(self.class_static), config)
            if self.semi_active is not None:
                rows["semi-active" + label] = (SemiActiveDamping(*self.semi_active), config)
            if self.schedule is not None:
                rows[schedule_label(self.certificate)] = (GainSchedule(self.schedule), config)
        rows["fixed"] = (ConstantGains(fixed_gains(n_joints=config.params.n_joints)), frozen)
        return rows


def evaluation_config(certificate: GainCertificate, setup: Setup | None = None,
                      delay: str | None = None, duration: float = 40.0,
                      dt: float = DEFAULT_DT) -> FlexTeleopConfig:
    """The settings a comparison runs under: the setup (its delays replaced if asked).

    Parameters
    ----------
    certificate : GainCertificate
        The tuner's certificate.
    setup : Setup, optional
        The setup; the paper's by default.
    delay : str, optional
        A delay spec for both directions in place of the setup's network.
    duration : float
        Episode length in seconds.
    dt : float
        Integration step in seconds.

    Returns
    -------
    FlexTeleopConfig
        The settings; a closed-form certificate of the setup's first plant is extended to its
        other plants and the ranges of its plants
        (:func:`~teleopkit.certification.verification.cover_plants`).
    """
    setup = setup if setup is not None else Setup.paper()
    if delay is not None:
        setup = setup.with_delay(delay)
    if (setup.other_plants or setup.plant_ranges) and certificate.covers_plant(setup.params):
        certificate = cover_plants(certificate, setup.plants, setup.ranges)
    return FlexTeleopConfig(setup, certificate, episode_length=duration, dt=dt)


def comparators_for(policy: GainPolicy, certificate: GainCertificate,
                    config: FlexTeleopConfig, cache: bool = True,
                    on_search: Callable[[], None] | None = None) -> Comparators:
    """The comparators of a question: stored with the policy, cached, or searched now.

    The comparators that do not depend on the tuner are cached on disk by their
    :meth:`Comparators.key` (the setup's fingerprint among it) in the directory of
    :func:`~teleopkit.certification.cache.cache_directory`.

    Parameters
    ----------
    policy : GainPolicy
        The tuner.
    certificate : GainCertificate
        Its certificate.
    config : FlexTeleopConfig
        Setup and episode settings.
    cache : bool
        Whether to read and write the disk cache.
    on_search : callable, optional
        Called before a search (none stored or cached), for example to say it takes minutes.

    Returns
    -------
    Comparators
        Comparators searched for this setup and certificate.
    """
    from teleopkit.certification.cache import cache_directory

    stored = Comparators.stored(policy, certificate, config)
    if stored is not None:
        return stored
    key = Comparators.key(certificate, config)
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    path = cache_directory() / "comparators" / f"{digest}.json"
    data = json.loads(path.read_text()) if cache and path.is_file() else {}
    if data.get("fingerprint") == key:
        static = Comparators.from_dict(data)
    else:
        if on_search is not None:
            on_search()
        _log.info("finding the comparators of %s for setup %s (a few minutes)",
                  certificate.gain_variation, config.setup.fingerprint)
        static = Comparators.find_static(certificate, config)
        if cache:
            from teleopkit.files import atomic_write

            path.parent.mkdir(parents=True, exist_ok=True)
            text = json.dumps(static.to_dict())
            atomic_write(path, lambda tmp: tmp.write_text(text))
    # the open-loop schedule is the policy's own: run it each time (one rollout)
    config = replace(config, certificate=certificate)
    return static.for_policy(policy, config) if static.semi_active is not None else static
