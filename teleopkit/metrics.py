"""Performance metrics of tracking and damping errors."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["error_metrics"]


def error_metrics(t: np.ndarray, errors: dict[str, np.ndarray]) -> pd.DataFrame:
    """RMS, integral of absolute error (IAE) and maximum of each error signal, per scenario.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Sample times.
    errors : dict of str to ndarray, shape (T, B, n)
        Named error signals (for example ``{"track": e_track, "damp": e_damp}``).

    Returns
    -------
    pandas.DataFrame
        One row per scenario, columns ``rms_<name>``, ``iae_<name>``, ``max_<name>`` computed on the
        Euclidean norm over joints (RMS and IAE by the trapezoidal rule over ``t``).
    """
    duration = float(t[-1] - t[0])
    columns: dict[str, np.ndarray] = {}
    for name, error in errors.items():
        norm = np.linalg.norm(error, axis=-1)
        columns[f"rms_{name}"] = np.sqrt(np.trapezoid(norm**2, t, axis=0) / duration)
        columns[f"iae_{name}"] = np.trapezoid(norm, t, axis=0)
        columns[f"max_{name}"] = norm.max(axis=0)
    return pd.DataFrame(columns).rename_axis("scenario")
