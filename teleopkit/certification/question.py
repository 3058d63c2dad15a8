"""A certification question as one frozen value: plant, gain box, delays and gain class.

:class:`Question` is what a certificate answers ("is every gain of this box, varying as this
class allows, stable for delays in these ranges on this plant?"). It checks its parts once, at
construction; the methods answer it (:func:`~teleopkit.certification.methods.certify_with`),
the cache keys certificates by it (:meth:`Question.key`), and
:func:`~teleopkit.certification.certifier.certify_gains` builds it from loose arguments.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import cast

from teleopkit._version import __version__
from teleopkit.certification.delay_bounds import check_delay_bounds, check_delay_floors
from teleopkit.certification.gain_classes import GainVariation, parse_gain_variation
from teleopkit.certification.gain_sets import GainBox
from teleopkit.model.params import TeleoperatorParams
from teleopkit.model.records import plant_record

__all__ = ["Question"]


def _check_types(params: object, box: object) -> None:
    """A one-line TypeError for a plant or a gain box of the wrong type, naming it."""
    for name, value, kind, hint in (
            ("params", params, TeleoperatorParams, "paper_setup() or a Setup's .params"),
            ("box", box, GainBox, "GainBox.uniform((K_min, K_max), (B_min, B_max))")):
        if not isinstance(value, kind):
            raise TypeError(f"{name} must be a {kind.__name__} ({hint}), got "
                            f"{type(value).__name__}")


@dataclass(frozen=True)
class Question:
    """What a certificate answers.

    Parameters
    ----------
    params : TeleoperatorParams
        The plant (local gains, operator, joints, arms).
    box : GainBox
        Remote gain ranges per joint.
    bounds : (float, float)
        Delay bounds ``(T_l*, T_r*)`` in seconds (positive).
    lower : (float, float)
        Minimum delays ``(T_l_min, T_r_min)`` in seconds, in ``[0, T_i*)``.
    variation : GainVariation or str
        The gain class (:mod:`teleopkit.certification.gain_classes`); a string is parsed.

    Raises
    ------
    ValueError
        One line naming a box of the wrong size, a stiffness range at 0, or bad delays.
    TypeError
        If ``params`` is not a :class:`~teleopkit.model.params.TeleoperatorParams` or ``box`` not
        a :class:`GainBox`.
    """

    params: TeleoperatorParams
    box: GainBox
    bounds: tuple[float, float] = (1.0, 1.0)
    lower: tuple[float, float] = (0.0, 0.0)
    variation: GainVariation | str = "frozen"

    def __post_init__(self) -> None:
        _check_types(self.params, self.box)
        if isinstance(self.variation, str):
            object.__setattr__(self, "variation", parse_gain_variation(self.variation))
        n = self.params.n_joints
        if self.box.n_joints != n:
            raise ValueError(f"gain box has {self.box.n_joints} joints, the teleoperator {n}")
        for i, (_, high) in enumerate(self.box.kr):
            if high <= 0:
                raise ValueError(f"K_r of joint {i + 1} is 0 everywhere in the box: a remote arm "
                                 "without stiffness does not follow the local one (nothing to "
                                 "certify)")
        bounds = check_delay_bounds(*self.bounds)
        object.__setattr__(self, "bounds", bounds)
        object.__setattr__(self, "lower", check_delay_floors(*self.lower, *bounds))

    @property
    def gain_class(self) -> GainVariation:
        """The gain class, parsed."""
        return cast(GainVariation, self.variation)  # parsed in __post_init__

    def key(self, method: str) -> str:
        """SHA-256 of the question answered by ``method`` (the teleopkit version included).

        Parameters
        ----------
        method : str
            The method (``"nuno"`` or ``"lmi"``).

        Returns
        -------
        str
            64 hex digits: the plant's fingerprint, the box, the delays, the method, the class.
        """
        question = {"plant": plant_record(self.params)["fingerprint"],
                    "box": self.box.to_dict(), "bounds": [float(b) for b in self.bounds],
                    "lower": [float(b) for b in self.lower], "method": method,
                    "variation": str(self.gain_class), "teleopkit": __version__}
        return hashlib.sha256(json.dumps(question, sort_keys=True).encode()).hexdigest()
