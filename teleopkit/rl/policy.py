"""A trained actor as plain numpy: fast single-sample inference, small ``.npz`` files, no torch.

:class:`GainPolicy` is what deployment, evaluation and campaigns run. The policies shipped in
``teleopkit/data`` have names (:data:`SHIPPED_POLICIES`) that :meth:`GainPolicy.load` and
``teleopkit evaluate --policy`` take in place of a file.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from teleopkit.rl.networks import Actor

__all__ = ["OUTPUT_MAPS", "PRETRAINED", "PRETRAINED_COVERED", "PRETRAINED_LAW",
           "SHIPPED_POLICIES", "GainPolicy", "check_output_map", "resolve_policy"]

PRETRAINED = "td3_policy.npz"
"""File name of the paper's tuner in ``teleopkit/data``: trained under the closed form's
frozen-gain certificate, which does not cover the schedules it plays
(``examples/train_pretrained.py``)."""

PRETRAINED_COVERED = "td3_covered_policy.npz"
"""File name of the shipped tuner trained under a certificate whose class covers every schedule
the safety layer lets through (its metadata holds the certificate;
``examples/train_covered.py``)."""

PRETRAINED_LAW = "law_policy.npz"
"""File name of the shipped gain law: the adaptive observation's levels, the delay and the tank
level to gains, searched by ``teleopkit search-law --setup mixed`` under ``tank:3``
(:mod:`teleopkit.rl.law_search`; its metadata holds the search settings and the setup)."""

SHIPPED_POLICIES: Mapping[str, str] = MappingProxyType({"covered": PRETRAINED_COVERED,
                                                         "law": PRETRAINED_LAW,
                                                         "paper": PRETRAINED})
"""Names of the shipped policies, with their files in ``teleopkit/data``: ``covered`` the TD3
tuner trained under the ``tank:3`` class, whose certificate covers every schedule it plays
(:data:`PRETRAINED_COVERED`); ``law`` the gain law searched for the mixed training distribution
under the same class (:data:`PRETRAINED_LAW`); ``paper`` the paper's tuner (:data:`PRETRAINED`)."""

_DATA = Path(__file__).resolve().parents[1] / "data"

OUTPUT_MAPS = ("softplus", "tanh")
"""The actor's output maps ``f`` in ``gains = low + span f(z)``: ``softplus(z)`` (the paper's,
unbounded above) or ``1 + tanh(z)`` (with ``span`` half the box's range: the box and nothing
beyond it)."""


def check_output_map(name: str, label: str = "output") -> None:
    """Refuse (one line) an output map that is not one of :data:`OUTPUT_MAPS`.

    Parameters
    ----------
    name : str
        The map's name.
    label : str
        What the message calls the setting.

    Raises
    ------
    ValueError
        If ``name`` is not a map's name.
    """
    if name not in OUTPUT_MAPS:
        raise ValueError(f"{label} must be one of {', '.join(OUTPUT_MAPS)}, got {name!r}")


def resolve_policy(source: str | Path) -> Path:
    """The file of a policy given by name (:data:`SHIPPED_POLICIES`) or by path.

    A shipped name is read as that name: write ``./covered`` for a file called ``covered``.

    Parameters
    ----------
    source : str or Path
        A shipped policy's name, or a policy file.

    Returns
    -------
    Path
        The file.

    Raises
    ------
    ValueError
        If ``source`` is neither a shipped name nor an existing file (one line listing the
        names).
    """
    if isinstance(source, str) and source in SHIPPED_POLICIES:
        return _DATA / SHIPPED_POLICIES[source]
    if not Path(source).is_file():
        raise ValueError(f"{source} is neither a policy file nor a shipped policy "
                         f"({', '.join(SHIPPED_POLICIES)})")
    return Path(source)


class GainPolicy:
    """A trained actor as plain numpy arrays: fast single-sample inference, small ``.npz`` files.

    Parameters
    ----------
    weights : sequence of (ndarray, ndarray)
        ``(W, b)`` of each linear layer, ``W`` of shape ``(out, in)``.
    obs_mean, obs_std : ndarray, shape (obs_dim,)
        Observation standardisation.
    low, span : ndarray, shape (act_dim,)
        Output map ``low + span * f(z)``, ``f`` given by ``output``.
    metadata : dict, optional
        JSON-serialisable information (training settings, baselines, ...).
    obs_range : tuple of ndarray, optional
        ``(lowest, highest)`` observation, each of shape ``(obs_dim,)``: observations are
        clipped into this range before anything else, so that the policy never extrapolates
        beyond what it was fitted on (for example the range seen while a gain law was
        searched). None: not clipped.
    output : {"softplus", "tanh"}
        The output map ``f``: ``softplus(z)`` (the paper's) or ``1 + tanh(z)``
        (:data:`OUTPUT_MAPS`).
    """

    def __init__(self, weights: list[tuple[np.ndarray, np.ndarray]], obs_mean: np.ndarray,
                 obs_std: np.ndarray, low: np.ndarray, span: np.ndarray,
                 metadata: dict[str, Any] | None = None,
                 obs_range: tuple[np.ndarray, np.ndarray] | None = None,
                 output: str = "softplus") -> None:
        check_output_map(output)
        self.output = output
        self.weights = [(np.asarray(w, dtype=np.float64), np.asarray(b, dtype=np.float64))
                        for w, b in weights]
        self.obs_mean = np.asarray(obs_mean, dtype=np.float64)
        self.obs_std = np.asarray(obs_std, dtype=np.float64)
        self.low = np.asarray(low, dtype=np.float64)
        self.span = np.asarray(span, dtype=np.float64)
        self.metadata = dict(metadata or {})
        self.obs_range = None if obs_range is None else (
            np.asarray(obs_range[0], dtype=np.float64), np.asarray(obs_range[1], dtype=np.float64))
        if self.obs_range is not None and not np.all(self.obs_range[0] <= self.obs_range[1]):
            raise ValueError("the observation range's lowest values must not exceed its highest")

    @classmethod
    def from_actor(cls, actor: Actor, metadata: dict[str, Any] | None = None) -> GainPolicy:
        """Copy an :class:`Actor`'s weights and maps.

        Parameters
        ----------
        actor : Actor
            Trained actor.
        metadata : dict, optional
            JSON-ready data stored with the policy (for example the training recipe).

        Returns
        -------
        GainPolicy
            The numpy policy.
        """
        from torch import nn

        linears = [m for m in actor.modules() if isinstance(m, nn.Linear)]
        weights = [(m.weight.detach().numpy().copy(), m.bias.detach().numpy().copy())
                   for m in linears]
        return cls(weights, actor.normalise.mean.numpy(), actor.normalise.std.numpy(),
                   actor.low.numpy(), actor.span.numpy(), metadata, output=actor.output)

    @property
    def fingerprint(self) -> str:
        """SHA-256 of the weights and maps, 16 hex digits (what the policy computes)."""
        digest = hashlib.sha256()
        if self.output != "softplus":  # the paper's map leaves the digest as it always was
            digest.update(self.output.encode())
        for array in (*(a for pair in self.weights for a in pair), self.obs_mean, self.obs_std,
                      self.low, self.span, *(self.obs_range or ())):
            digest.update(np.ascontiguousarray(array).tobytes())
        return digest.hexdigest()[:16]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Raw gains for one observation ``(obs_dim,)`` or a batch ``(B, obs_dim)``."""
        x = np.asarray(obs, dtype=np.float64)
        if self.obs_range is not None:
            x = np.clip(x, *self.obs_range)
        x = (x - self.obs_mean) / self.obs_std
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(self.weights):
            x = x @ w.T + b
            if i < last:
                np.maximum(x, 0.0, out=x)
        mapped = np.logaddexp(0.0, x) if self.output == "softplus" else 1.0 + np.tanh(x)
        return self.low + self.span * mapped

    def save(self, path: str | Path) -> None:
        """Write an ``.npz`` file (no pickled objects).

        Parameters
        ----------
        path : str or Path
            Destination file.
        """
        arrays: dict[str, Any] = {"obs_mean": self.obs_mean, "obs_std": self.obs_std,
                                         "low": self.low, "span": self.span,
                                         "output": np.array(self.output),
                                         "metadata": np.array(json.dumps(self.metadata))}
        for i, (w, b) in enumerate(self.weights):
            arrays[f"w{i}"], arrays[f"b{i}"] = w.astype(np.float32), b.astype(np.float32)
        if self.obs_range is not None:
            arrays["obs_lowest"], arrays["obs_highest"] = self.obs_range
        with open(path, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> GainPolicy:
        """Read a file written by :meth:`save`, or a shipped policy by name.

        Parameters
        ----------
        path : str or Path
            ``.npz`` file, or the name of a shipped policy (:data:`SHIPPED_POLICIES`, for
            example ``"covered"``).

        Returns
        -------
        GainPolicy
            The policy.

        Raises
        ------
        ValueError
            If the file is not a policy file, or there is no such file or shipped policy.
        """
        path = resolve_policy(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                layers = sum(1 for key in data.files if key.startswith("w"))
                weights = [(data[f"w{i}"], data[f"b{i}"]) for i in range(layers)]
                metadata = json.loads(str(data["metadata"]))
                clipped = "obs_lowest" in data.files
                output = str(data["output"]) if "output" in data.files else "softplus"
                return cls(weights, data["obs_mean"], data["obs_std"], data["low"],
                           data["span"], metadata,
                           (data["obs_lowest"], data["obs_highest"]) if clipped else None,
                           output)
        except KeyError as error:
            raise ValueError(f"{path} is not a teleopkit policy file (no {error} array)") from None
        except (ValueError, EOFError, OSError, zipfile.BadZipFile):
            raise ValueError(f"{path} is not a teleopkit policy file (not an .npz archive "
                             "written by GainPolicy.save)") from None

    @classmethod
    def pretrained(cls, name: str = PRETRAINED) -> GainPolicy:
        """A small policy shipped in ``teleopkit/data``.

        Parameters
        ----------
        name : str
            A name of :data:`SHIPPED_POLICIES`, or a file name: :data:`PRETRAINED` (the paper's
            tuner) or :data:`PRETRAINED_COVERED`.

        Returns
        -------
        GainPolicy
            The policy.
        """
        return cls.load(_DATA / SHIPPED_POLICIES.get(name, name))

    @property
    def action_dim(self) -> int:
        """Number of gains produced."""
        return self.low.size
