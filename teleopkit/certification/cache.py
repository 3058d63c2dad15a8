"""Certificates kept on disk by the question they answer, re-verified whenever they are reused.

Two-joint LMI certificates take minutes; asking the same question again should not. A question
is the plant (its :func:`~teleopkit.model.params.plant_record` fingerprint), the gain box, the
delay bounds and minimum delays, the method and the gain class; its SHA-256 names a JSON file
in the cache directory (``$TELEOPKIT_CACHE``, else ``~/.cache/teleopkit``). A file read back
goes through :func:`~teleopkit.certification.verification.load_certificate`, which re-checks
every proof against the plant, so an edited or stale file is never trusted: it is
recomputed and overwritten.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from teleopkit._version import __version__
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.verification import load_certificate
from teleopkit.files import atomic_write
from teleopkit.model.params import TeleoperatorParams, plant_record

__all__ = ["cache_directory", "cached", "question_key"]


def cache_directory() -> Path:
    """Where certificates are kept: ``$TELEOPKIT_CACHE``, else ``~/.cache/teleopkit``.

    Returns
    -------
    pathlib.Path
        The directory (not created until a certificate is written).
    """
    root = os.environ.get("TELEOPKIT_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "teleopkit"


def question_key(params: TeleoperatorParams, box: GainBox, bounds: tuple[float, float],
                 lower: tuple[float, float], method: str, variation: str) -> str:
    """The SHA-256 of a certification question (the teleopkit version included).

    Parameters
    ----------
    params : TeleoperatorParams
        The plant.
    box : GainBox
        The remote gain box.
    bounds, lower : tuple of float
        Delay bounds ``(T_l*, T_r*)`` and minimum delays ``(T_l_min, T_r_min)`` in seconds.
    method, variation : str
        Certification method and gain class.

    Returns
    -------
    str
        64 hex digits.
    """
    question = {"plant": plant_record(params)["fingerprint"], "box": box.to_dict(),
                "bounds": [float(b) for b in bounds], "lower": [float(b) for b in lower],
                "method": method, "variation": variation, "teleopkit": __version__}
    return hashlib.sha256(json.dumps(question, sort_keys=True).encode()).hexdigest()


def cached(key: str, compute: Callable[[], GainCertificate],
           directory: Path | None = None) -> tuple[GainCertificate, bool]:
    """The certificate stored under ``key`` (re-verified), else ``compute()`` stored there.

    Parameters
    ----------
    key : str
        :func:`question_key` of the question.
    compute : callable
        Computes the certificate when none is stored or the stored one does not verify.
    directory : pathlib.Path, optional
        Cache directory; :func:`cache_directory` by default.

    Returns
    -------
    certificate : GainCertificate
        The certificate.
    reused : bool
        Whether it came from the cache.
    """
    path = (directory if directory is not None else cache_directory()) / f"{key}.json"
    try:
        return load_certificate(path.read_text()), True
    except (OSError, ValueError):  # absent, unreadable, edited or stale: recompute
        pass
    certificate = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: tmp.write_text(certificate.to_json()))
    except OSError:  # a read-only home: the answer stands, it is just not kept
        pass
    return certificate, False
