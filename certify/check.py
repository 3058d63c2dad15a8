"""Numpy re-check of LMI conditions from stored decision matrices."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from certify.channels import Channels
from certify.conditions import LMIMethod
from certify.system import PolytopicDelaySystem
from certify.system_data import SystemData

__all__ = ["RTOL", "relative_margin", "residuals", "variables_valid"]

RTOL = 1e-9
"""Smallest accepted relative eigenvalue margin ``lambda_min(F) / max|lambda(F)|``."""


def relative_margin(matrix: NDArray[np.float64]) -> float:
    """Smallest eigenvalue of the symmetric part of ``matrix``, relative to its largest modulus.

    Parameters
    ----------
    matrix : numpy.ndarray
        Square matrix (the quadratic form only depends on its symmetric part).

    Returns
    -------
    float
        ``lambda_min / max |lambda|`` (``0.0`` for the zero matrix, ``-inf`` if not finite).
    """
    sym = 0.5 * (matrix + matrix.T)
    if not np.all(np.isfinite(sym)):
        return -np.inf
    eig = np.linalg.eigvalsh(sym)
    scale = float(np.max(np.abs(eig)))
    return float(eig[0] / scale) if scale > 0.0 else 0.0


def variables_valid(
    method: LMIMethod,
    system: PolytopicDelaySystem,
    ch: Channels,
    mu: float | None,
    matrices: Mapping[str, NDArray[np.float64]],
    data: SystemData | None = None,
) -> bool:
    """Check that ``matrices`` holds every decision matrix with its shape and symmetry.

    Parameters
    ----------
    method : LMIMethod
        The method whose variables are expected.
    system : PolytopicDelaySystem
        The system (its vertices, parameter variation and uncertainty fix the variables).
    ch : Channels
        Delay channels.
    mu : float or None
        Delay-derivative bound.
    matrices : Mapping[str, numpy.ndarray]
        Stored decision matrices.
    data : SystemData, optional
        The system's numbers the matrices were solved for (they fix the slacks' shape);
        :func:`certify.system_data.system_data` by default.

    Returns
    -------
    bool
        ``True`` when exactly the expected matrices are present, finite, of the right shape,
        and symmetric where required.
    """
    specs = method.variables(ch, mu, system, data)
    if set(matrices) != {spec.name for spec in specs}:
        return False
    for spec in specs:
        value = matrices.get(spec.name)
        if value is None or value.shape != spec.shape or not np.all(np.isfinite(value)):
            return False
        if spec.symmetric and not np.array_equal(value, value.T):
            return False
    return True


def residuals(
    method: LMIMethod,
    system: PolytopicDelaySystem,
    ch: Channels,
    matrices: Mapping[str, NDArray[np.float64]],
    h: Sequence[float],
    mu: float | None,
    data: SystemData | None = None,
) -> dict[str, float]:
    """Relative eigenvalue margins of every condition, recomputed in numpy.

    Parameters
    ----------
    method : LMIMethod
        The method.
    system : PolytopicDelaySystem
        The system.
    ch : Channels
        Delay channels of the system.
    matrices : Mapping[str, numpy.ndarray]
        Decision matrices.
    h : sequence of float
        Delay bounds.
    mu : float or None
        Delay-derivative bound.
    data : SystemData, optional
        The system's numbers, as in :func:`variables_valid`.

    Returns
    -------
    dict
        Condition name -> :func:`relative_margin` of its matrix (positive means satisfied).
    """
    h2 = [float(x) ** 2 for x in h]
    conds = method.conditions(system, ch, matrices, [float(x) for x in h], h2, mu, data)
    return {c.name: relative_margin(np.asarray(c.matrix, dtype=np.float64)) for c in conds}
